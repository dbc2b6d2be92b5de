"""Training metrics: one CSV row per episode and the training-curve plot drawn from it.

The CSV is the source of truth; the plot is redrawn from it, so a resumed run's curves show the
whole history. Columns may appear late (losses exist only after the warm-up); a new column rewrites
the file with the wider header, and earlier rows leave the new cell empty.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

METRICS_FILE = "metrics.csv"
"""Name of the per-episode metrics file in a run folder."""
CURVES_FILE = "training_curves.png"
"""Name of the training-curve plot in a run folder."""
ROLLING_WINDOW = 25
"""Episodes in the rolling mean drawn over noisy per-episode curves."""

AGENT_NAMES = ("B", "psi_K")
"""The two agents, as named in metric columns (``charts/return_B``, ``actions/psi_K_bin3``)."""


def histogram_column(agent: str, bin_index: int) -> str:
    """Column holding the count of ``agent``'s executed actions that fell in bin ``bin_index``."""
    return f"actions/{agent}_bin{bin_index}"


class MetricsLog:
    """Per-episode metrics appended to a CSV file (existing rows are kept when resuming)."""

    def __init__(self, path: Path, base_columns: Sequence[str]) -> None:
        self.path = path
        self.columns: list[str] = list(base_columns)
        self.rows: list[dict[str, str]] = []
        if path.exists():
            with path.open(newline="") as handle:
                reader = csv.DictReader(handle)
                for name in reader.fieldnames or []:
                    if name not in self.columns:
                        self.columns.append(name)
                self.rows = [dict(row) for row in reader]
        self._rewrite()

    def keep_episodes_before(self, episode: int) -> int:
        """Drop the rows of episodes ``episode`` and later (a run resumed from an earlier
        checkpoint trains them again); the number of rows dropped."""
        kept = [row for row in self.rows if _episode(row) < episode]
        dropped = len(self.rows) - len(kept)
        if dropped:
            self.rows = kept
            self._rewrite()
        return dropped

    def append(self, row: Mapping[str, object]) -> None:
        """Add one episode's row; new column names widen the header (the file is rewritten)."""
        text = {key: _cell(value) for key, value in row.items()}
        new_columns = [key for key in text if key not in self.columns]
        self.rows.append(text)
        if new_columns:
            self.columns.extend(new_columns)
            self._rewrite()
            return
        with self.path.open("a", newline="") as handle:
            csv.DictWriter(handle, self.columns, restval="").writerow(text)

    def _rewrite(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        temporary = self.path.with_suffix(".csv.tmp")
        with temporary.open("w", newline="") as handle:
            writer = csv.DictWriter(handle, self.columns, restval="")
            writer.writeheader()
            writer.writerows(self.rows)
        temporary.replace(self.path)


def _episode(row: Mapping[str, str]) -> int:
    """A row's episode number (a row without one counts as before every episode)."""
    try:
        return int(row.get("episode") or -1)
    except ValueError:
        return -1


def _cell(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return str(int(value))
    if isinstance(value, float):
        return repr(value)  # nan and inf as such: a diverged loss is not a missing one
    return str(value)


def read_metrics(path: Path) -> dict[str, list[float]]:
    """The numeric columns of a metrics CSV (empty or non-numeric cells become NaN)."""
    with path.open(newline="") as handle:
        reader = csv.DictReader(handle)
        columns: dict[str, list[float]] = {name: [] for name in reader.fieldnames or []}
        for row in reader:
            for name, values in columns.items():
                try:
                    values.append(float(row.get(name) or "nan"))
                except ValueError:
                    values.append(math.nan)
    return columns


def plot_training_curves(metrics_path: Path, output: Path, bins: int) -> Path:
    """Draw returns, losses, mean Q and the action histograms of each agent to ``output``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    data = read_metrics(metrics_path)
    episodes = np.asarray(data.get("episode", []), dtype=float)
    figure, axes = plt.subplots(2, 3, figsize=(16, 8.5), constrained_layout=True)

    def curve(axis, column: str, label: str) -> None:
        values = np.asarray(data.get(column, []), dtype=float)
        finite = np.isfinite(values)
        if not finite.any():
            return
        x, y = episodes[finite], values[finite]
        axis.plot(x, y, alpha=0.25, linewidth=0.8)
        window = min(ROLLING_WINDOW, len(y))
        smooth = np.convolve(y, np.ones(window) / window, mode="valid")
        marker = "o" if len(smooth) < 3 else None  # a line of one point is not drawn
        axis.plot(x[window - 1 :], smooth, marker=marker, label=f"{label} (mean of {window})")

    def note_if_empty(axis, text: str) -> None:
        if not axis.lines:
            axis.text(0.5, 0.5, text, ha="center", va="center", transform=axis.transAxes)

    for agent, axis in zip(AGENT_NAMES, axes[0, :2], strict=True):
        curve(axis, f"charts/return_{agent}", f"return {agent}")
        axis.set_title(f"episode return, {agent} agent")
        axis.set_xlabel("episode")
        axis.legend(loc="best", fontsize=8) if axis.lines else None
        note_if_empty(axis, f"no {agent} episode yet")
    loss_axis = axes[0, 2]
    for agent in AGENT_NAMES:
        curve(loss_axis, f"losses/critic_{agent}", f"critic loss {agent}")
    loss_axis.set_yscale("log") if loss_axis.lines else None
    loss_axis.set_title("critic losses")
    loss_axis.set_xlabel("episode")
    loss_axis.legend(loc="best", fontsize=8) if loss_axis.lines else None
    warming_up = "no gradient step yet\n(the replay buffers are still in their warm-up)"
    note_if_empty(loss_axis, warming_up)
    q_axis = axes[1, 2]
    for agent in AGENT_NAMES:
        curve(q_axis, f"losses/actor_{agent}", f"actor loss {agent} (= -mean Q)")
        curve(q_axis, f"losses/mean_q_{agent}", f"mean Q {agent}")
    q_axis.set_title("actor losses and mean Q")
    q_axis.set_xlabel("episode")
    q_axis.legend(loc="best", fontsize=7) if q_axis.lines else None
    note_if_empty(q_axis, warming_up)

    for agent, axis in zip(AGENT_NAMES, axes[1, :2], strict=True):
        counts = np.asarray(
            [data.get(histogram_column(agent, index), []) for index in range(bins)], dtype=float
        )
        axis.set_title(f"executed {agent} per episode (share per bin)")
        axis.set_xlabel("episode")
        axis.set_ylabel(f"{agent} bin (low to high)")
        if counts.size == 0 or not np.isfinite(counts).any():
            continue
        counts = np.nan_to_num(counts)
        totals = counts.sum(axis=0, keepdims=True)
        share = np.divide(counts, totals, out=np.zeros_like(counts), where=totals > 0)
        # Each column spans its episode +- 0.5 (a one-episode run gets a column of width 1).
        extent = (
            (episodes.min() - 0.5, episodes.max() + 0.5, -0.5, bins - 0.5)
            if len(episodes)
            else None
        )
        image = axis.imshow(share, aspect="auto", origin="lower", extent=extent, vmin=0, vmax=1)
        figure.colorbar(image, ax=axis, fraction=0.04)
    from matplotlib.ticker import MaxNLocator

    for axis in axes.flat:  # episodes are whole numbers (a short run got ticks at 0.25, 0.5)
        axis.xaxis.set_major_locator(MaxNLocator(integer=True))
    figure.suptitle(f"LIT* Fuzzy-DDPG training ({metrics_path.parent.name})")
    output.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(output, dpi=110)
    plt.close(figure)
    return output
