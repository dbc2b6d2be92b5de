"""``lit tensors``: look into lookup tensors, and make them without training.

::

    lit tensors info [DIR]
    lit tensors constant --b 200 --psi-k 6 --out DIR

``info`` checks each tensor of a folder as the planner does (the C++ reader's checks plus the data
hash) and prints what it holds: the output and its range, the spread of its values over the grid,
the decision interval the tensor policy applies, and where it came from. ``--json`` prints one
JSON object.

``constant`` writes ``b_tensor`` and/or ``k_tensor`` (with their sidecars) that hold one value
everywhere. The ``tensor`` policy then plays a constant policy through the same files, lookups and
planner code as trained tensors, so ``lit bench --tensors DIR`` measures what the best constant
of a parameter can do: a bound a learned policy of that parameter has to beat to have learned
anything about the features. A parameter left out gets no file and falls back to the fixed value
(B = 100, psi_K = e), as with trained tensors. ``--decision-interval N`` names the psi_K
decision interval in the sidecar, as ``lit train`` does, and the tensor policy applies it.

Exit status: ``info`` 0 when every tensor in the folder passed its checks, 2 when the folder
holds none or one is defective (that one named with its problem; the others are still shown).
``constant`` 0 written, 2 bad input (a value outside the output's range, a B that is not a whole
number, no value, any tensor file already in the folder) or a failed write, reported as one line
on stderr; nothing is written then (a failed write removes what it wrote).
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from lit_planner import argtypes, planning, tensor_files
from lit_planner.errors import LitPlannerError, TensorFileError
from lit_planner.safe_logger import SafeLogger

EXIT_WRITTEN = 0
"""The tensors were written."""
EXIT_BAD_INPUT = 2
"""Nothing was written."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``lit tensors``."""
    # Replaces the one-line summary of `lit --help` (lit_planner.cli), which names only `constant`.
    parser.description = (
        "Look into lookup tensors and make them without training: info checks a folder's tensors "
        "and shows what they hold; constant writes tensors holding one value everywhere, a "
        "baseline for lit bench --tensors."
    )
    commands = parser.add_subparsers(dest="tensors_command", metavar="ACTION", required=True)
    info = commands.add_parser(
        "info",
        help="check a folder's tensors and show what they hold and where they came from",
        description="Check each tensor of the folder as the planner does and show its output, "
        "the spread of its values, the decision interval it is used with, and its provenance.",
    )
    info.add_argument(
        "folder",
        nargs="?",
        type=argtypes.path,
        metavar="DIR",
        help=f"tensor folder (default: ${planning.TENSORS_ENV}, else the checkout's tensors/)",
    )
    info.add_argument("--json", action="store_true", help="print one JSON object")
    constant = commands.add_parser(
        "constant",
        help="write tensors that hold one value everywhere (a constant policy for lit bench)",
        description="Write b_tensor and/or k_tensor holding one value everywhere, with their "
        "sidecars. The tensor policy then plays that constant; a parameter left out falls back "
        "to the fixed value (B = 100, psi_K = e).",
    )
    low_b, high_b = _range("B")
    low_k, high_k = _range("psi_K")
    constant.add_argument(
        "--b", type=float, metavar="B", help=f"batch size, a whole number {low_b:g}..{high_b:g}"
    )
    constant.add_argument(
        "--psi-k", type=float, metavar="PSI", help=f"neighbour factor psi_K, {low_k:g}..{high_k:g}"
    )
    constant.add_argument(
        "--decision-interval",
        type=int,
        metavar="N",
        help="with --psi-k: decide psi_K every N expansions, as a tensor trained with "
        "lit train --decision-interval N is used (default: not named, the planner's every "
        "expansion)",
    )
    constant.add_argument(
        "--out",
        type=argtypes.path,
        required=True,
        metavar="DIR",
        help="folder to write into (created)",
    )


def run(args: argparse.Namespace) -> int:
    """Run ``lit tensors``; its exit status."""
    if args.tensors_command == "info":
        return _info(args)
    try:
        written = write_constant(
            args.out,
            args.b,
            args.psi_k,
            command=_command(),
            decision_interval=args.decision_interval,
        )
    except LitPlannerError as error:
        print(f"lit tensors: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    for output, path in written.items():
        print(f"lit tensors: {path}: {output} = {_value(args, output):g} everywhere")
    if args.decision_interval:
        print(f"lit tensors: psi_K is decided every {args.decision_interval} expansions")
    print(f"lit tensors: use them with --tensors {args.out} (lit bench, lit plan --policy tensor)")
    return EXIT_WRITTEN


PERCENTILES = (0, 5, 25, 50, 75, 95, 100)
"""Spread of a tensor's values shown by ``info``."""
PROVENANCE_SHOWN = ("command", "constant", "episodes", "wall_time_s", "git_commit", "note")
"""Provenance entries ``info`` prints in its readable form (``--json`` gives all)."""


def describe(folder: Path) -> dict[str, object]:
    """What ``lit tensors info`` shows of ``folder``: one entry per tensor file name, each either
    a description or ``{"error": message}`` for a defective tensor, and the folder's own
    ``"error"`` when its tensors cannot be used together (their sidecars name different lookup
    modes).

    Raises:
        TensorFileError: ``folder`` is not a folder or holds no tensor.
    """
    if not folder.is_dir():
        raise TensorFileError(f"{folder}: not a folder")
    found = {
        output: folder / name
        for output, name in planning.TENSOR_FILES.items()
        if (folder / name).exists() or tensor_files.sidecar_path(folder / name).exists()
    }
    if not found:
        raise TensorFileError(
            f"{folder}: no tensors ({' or '.join(planning.TENSOR_FILES.values())} with sidecars)"
        )
    tensors: dict[str, object] = {}
    for output, path in found.items():
        try:
            values, sidecar = tensor_files.read_tensor(path)
            if sidecar.output != output:
                raise TensorFileError(f"{path}: holds {sidecar.output}, expected {output}")
            interval = planning.trained_decision_interval(path) if output == "psi_K" else None
        except TensorFileError as error:
            tensors[path.name] = {"error": str(error)}
            continue
        spread = np.percentile(values, PERCENTILES)
        entry: dict[str, object] = {
            "output": output,
            "range": list(sidecar.value_range),
            "rounding": sidecar.rounding,
            "interpolation": sidecar.interpolation,
            "percentiles": {f"p{p}": float(v) for p, v in zip(PERCENTILES, spread, strict=True)},
            "created": sidecar.created,
            "policy_version": sidecar.policy_version,
            "data_sha256": sidecar.data_sha256,
            "checkpoint_sha256": sidecar.checkpoint_sha256,
            "provenance": dict(sidecar.provenance),
            "training": dict(sidecar.training),
        }
        if output == "psi_K":
            entry["decision_interval"] = interval or None
        tensors[path.name] = entry
    document: dict[str, object] = {"folder": str(folder), "tensors": tensors}
    readable = [output for output, path in found.items() if "error" not in tensors[path.name]]
    if len(readable) > 1:
        try:  # what the planner checks of the folder as a whole, beyond each tensor
            planning.sidecar_interpolation(folder, readable)
        except TensorFileError as error:
            document["error"] = str(error)
    return document


def _info(args: argparse.Namespace) -> int:
    folder = planning.default_tensors_dir() if args.folder is None else args.folder
    try:
        document = describe(folder)
    except TensorFileError as error:
        print(f"lit tensors: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    tensors = document["tensors"]
    assert isinstance(tensors, dict)
    defective = [entry["error"] for entry in tensors.values() if "error" in entry]
    if "error" in document:  # the folder as a whole: the tensors disagree
        defective.append(str(document["error"]))
    if args.json:
        print(json.dumps(document))
    else:
        print(f"{folder}:")
        for name, entry in tensors.items():
            print("\n".join(_info_lines(name, entry)))
    for message in defective:
        print(f"lit tensors: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT if defective else EXIT_WRITTEN


def _info_lines(name: str, entry: dict[str, object]) -> list[str]:
    if "error" in entry:
        return [f"  {name}: DEFECTIVE (see below)"]
    low, high = entry["range"]  # type: ignore[misc]
    spread = entry["percentiles"]
    assert isinstance(spread, dict)
    head = (
        f"  {name}: {entry['output']} in {low:g}..{high:g} (rounding {entry['rounding']}), "
        f"{entry['interpolation']} lookup, checked"
    )
    lines = [
        head,
        "    values      " + ", ".join(f"{key} {value:.4g}" for key, value in spread.items()),
    ]
    if entry["output"] == "psi_K":
        interval = entry["decision_interval"]
        lines.append(
            f"    interval    psi_K decided every {interval} expansions (as trained)"
            if interval
            else "    interval    not named: the planner's default (every expansion) applies"
        )
    training = entry.get("training") or {}
    assert isinstance(training, dict)
    if "updates" in training:  # a learner's export (constant tensors have none)
        lines.append(
            f"    training    {training['updates']} gradient updates from "
            f"{training.get('transitions', '?')} transitions"
            + ("; UNTRAINED: the actor's initial weights" if not training["updates"] else "")
        )
    provenance = entry["provenance"]
    assert isinstance(provenance, dict)
    lines.append(
        f"    created     {SafeLogger.text(entry['created'])}, policy version "
        f"{SafeLogger.text(entry['policy_version'])}"
    )
    lines += [
        f"    {key:<11s} {SafeLogger.text(provenance[key])}"
        for key in PROVENANCE_SHOWN
        if key in provenance
    ]
    resumes = provenance.get("resumed_with") or []
    if isinstance(resumes, list) and resumes:  # the run's last command, the export's own
        lines.append(
            f"    {'resumed':<11s} {SafeLogger.text(resumes[-1])}"
            + (f" (the last of {len(resumes)} resumes)" if len(resumes) > 1 else "")
        )
    return lines


def write_constant(
    folder: Path,
    b: float | None,
    psi_k: float | None,
    command: str | None = None,
    decision_interval: int | None = None,
) -> dict[str, Path]:
    """Write a constant ``b_tensor`` (value ``b``) and/or ``k_tensor`` (``psi_k``) into
    ``folder``; returns the ``.npy`` paths written by output name. ``decision_interval`` (with
    ``psi_k``) goes into the psi_K sidecar's provenance, which the tensor policy applies.

    Raises:
        TensorFileError: no value, a value outside its output's range or not finite, B not a whole
            number, an interval below 1 or without ``psi_k``, ``folder`` not a folder, any tensor
            file or sidecar already in it (a tensor left there would be played with the new one),
            or the files could not be written (then none of them stays). All but the last are
            checked before anything is written.
    """
    values = {output: value for output, value in (("B", b), ("psi_K", psi_k)) if value is not None}
    if not values:
        raise TensorFileError("give --b and/or --psi-k: the value(s) to write")
    for output, value in values.items():
        low, high = _range(output)
        if not (math.isfinite(value) and low <= value <= high):
            raise TensorFileError(f"{output} = {value:g} is outside its range {low:g}..{high:g}")
    if b is not None and b != round(b):
        raise TensorFileError(f"B = {b:g} is not a whole number")
    if decision_interval is not None:
        if psi_k is None:
            raise TensorFileError("--decision-interval applies to psi_K: give --psi-k too")
        if not 1 <= decision_interval <= planning.MAX_DECISION_INTERVAL:
            raise TensorFileError(
                f"--decision-interval must be a whole number 1..{planning.MAX_DECISION_INTERVAL}, "
                f"got {decision_interval}"
            )
    if folder.exists() and not folder.is_dir():
        raise TensorFileError(f"{folder}: a file, not a folder")
    for name in planning.TENSOR_FILES.values():
        for existing in (folder / name, tensor_files.sidecar_path(folder / name)):
            if existing.exists():
                raise TensorFileError(f"{existing}: already there; choose another --out")
    created = datetime.now(UTC)
    try:
        with tensor_files.staged_folder(folder) as stage:  # all or nothing
            for output, value in values.items():
                stored = float(np.float32(value))
                provenance: dict[str, object] = {"constant": stored}
                if command:
                    provenance["command"] = command
                if output == "psi_K" and decision_interval is not None:
                    provenance["decision_interval"] = decision_interval
                tensor_files.write_tensor(
                    stage / planning.TENSOR_FILES[output],
                    np.full(tensor_files.TENSOR_SHAPE, stored, dtype=tensor_files.TENSOR_DTYPE),
                    output,
                    provenance=provenance,
                    created=created,
                )
    except OSError as error:
        raise TensorFileError(f"{folder}: tensors not written: {error}") from error
    return {output: folder / planning.TENSOR_FILES[output] for output in values}


def _command() -> str:
    return "lit " + shlex.join(sys.argv[1:])


def _value(args: argparse.Namespace, output: str) -> float:
    return float(args.b if output == "B" else args.psi_k)


def _range(output: str) -> tuple[float, float]:
    consequents = tensor_files.OUTPUTS[output].consequents
    return min(consequents), max(consequents)
