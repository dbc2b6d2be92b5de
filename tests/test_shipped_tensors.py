"""The shipped tensors (``tensors/``) trace back to the bag of the training run that made them.

``tensors/provenance.json`` names the run folder; exactly one bag under ``bags/`` was recorded by
that run (``lit.run_folder`` in its metadata; bags not in git do not count). The bag holds one episode summary per trained
episode with every publisher's ``seq`` unbroken, and both sidecars carry the same provenance.
The shipped evaluations (``tensors/evaluation_summary.md``, ``tensors/paper/summary.md``) are what
``lit replay bench`` makes of their shipped bags.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml

from lit_planner import replay, tensor_files

ROOT = Path(__file__).resolve().parents[1]
TENSORS = ROOT / "tensors"


def _bags_of(run_folder: str) -> list[Path]:
    """The bags in git (not a local copy, a salvaged one or a user's own run) recorded by it."""
    listed = subprocess.run(
        ["git", "ls-files", "-z", "--", "bags/**/metadata.yaml"],
        cwd=ROOT, capture_output=True, text=True, check=True,
    )  # fmt: skip
    found = []
    for metadata in sorted(ROOT / name for name in listed.stdout.split("\0") if name):
        info = yaml.safe_load(metadata.read_text(encoding="utf-8"))["rosbag2_bagfile_information"]
        if (info.get("custom_data") or {}).get("lit.run_folder") == run_folder:
            found.append(metadata.parent)
    return found


def test_shipped_tensors_trace_to_their_training_bag(tmp_path: Path) -> None:
    provenance = json.loads((TENSORS / "provenance.json").read_text(encoding="utf-8"))
    (bag,) = _bags_of(provenance["run_folder"])
    info = replay.bag_info(bag)
    assert info["custom_data"]["lit.source"] == "lit_train"
    if "run_id" in provenance:
        assert info["custom_data"]["lit.run_id"] == provenance["run_id"]
    counts = {topic["topic"]: topic["messages"] for topic in info["topics"]}
    assert counts["/lit/episode"] == provenance["episodes"]
    assert all(p["gaps"] == 0 and p["missing"] == 0 for p in info["publishers"])
    assert info["skipped"]["total"] == 0
    for name in ("b_tensor.npy", "k_tensor.npy"):
        _, sidecar = tensor_files.read_tensor(TENSORS / name)
        assert sidecar.provenance == provenance
    # lit replay tensors of this bag records the interval the tensors were trained with (from
    # the bag's lit train command), also when given the .mcap file; a bench bag (no training
    # episodes) does not count, a bag of another interval is refused together with it, and so is
    # a --decision-interval that contradicts it.
    from lit_learner.offline import recorded_decision_interval
    from lit_planner.replay import ReplayError

    assert recorded_decision_interval([bag]).value == provenance["decision_interval"] == 10
    assert recorded_decision_interval(list(bag.glob("*.mcap"))).value == 10
    samples = ROOT / "bags" / "samples"
    assert recorded_decision_interval([bag, samples / "bench_np4"]).value == 10
    other = tmp_path / "other"
    shutil.copytree(samples / "bench_np4", other)
    metadata = yaml.safe_load((other / "metadata.yaml").read_text(encoding="utf-8"))
    custom = metadata["rosbag2_bagfile_information"]["custom_data"]
    custom.update({"lit.source": "lit_train", "lit.decision_interval": "3"})
    (other / "metadata.yaml").write_text(yaml.safe_dump(metadata), encoding="utf-8")
    with pytest.raises(ReplayError, match="different psi_K decision intervals"):
        recorded_decision_interval([bag, other])
    with pytest.raises(ReplayError, match="--decision-interval 1 contradicts the bags"):
        recorded_decision_interval([bag], 1)
    custom["lit.decision_interval"] = "ten"
    (other / "metadata.yaml").write_text(yaml.safe_dump(metadata), encoding="utf-8")
    with pytest.raises(ReplayError, match="not a whole number"):
        recorded_decision_interval([other])


@pytest.mark.parametrize(
    ("bag", "summary"),
    [
        ("tensor-eval-20261207", "evaluation_summary.md"),
        ("tensor-paper-20261207", "paper/summary.md"),
    ],
)
def test_shipped_evaluations_are_what_their_bags_give(
    tmp_path: Path, bag: str, summary: str
) -> None:
    """The shipped tables (the numbers the READMEs quote) regenerate from the shipped bags: `lit
    replay bench` writes the same summary.md, text for text."""
    import subprocess
    import sys

    process = subprocess.run(
        [
            sys.executable, "-m", "lit_planner.cli", "replay", "bench",
            str(ROOT / "bags" / "shipped" / bag), "--out", str(tmp_path / "out"),
        ],
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert process.returncode == 0, process.stderr
    regenerated = (tmp_path / "out" / "summary.md").read_text(encoding="utf-8")
    assert regenerated == (TENSORS / summary).read_text(encoding="utf-8")


def test_replay_verify_of_the_shipped_training_bag_passes_every_path() -> None:
    """The README's evidence for the dense re-check: `lit replay verify` of the shipped training
    bag reports all 3920 paths valid, exit 0. One of them (rrd4 instance 458, /lit/episode seq
    2145) clips a box corner between the planner's checks, over 1.34e-6 against their spacing of
    1e-5: it failed the re-check (exit 1) until such clips passed on 2026-12-06."""
    import subprocess
    import sys

    process = subprocess.run(
        [sys.executable, "-m", "lit_planner.cli", "replay", "verify",
         str(ROOT / "bags" / "shipped" / "train-20261130c")],
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    text = process.stdout + process.stderr
    assert process.returncode == 0, text
    assert "3920 paths checked: 3920 valid, 0 invalid" in text, text
