"""``lit tensors``: make lookup tensors without training.

::

    lit tensors constant --b 200 --psi-k 6 --out DIR

``constant`` writes ``b_tensor`` and/or ``k_tensor`` (with their sidecars) that hold one value
everywhere. The ``tensor`` policy then plays a constant policy through the same files, lookups and
planner code as trained tensors, so ``lit bench --tensors DIR`` measures what the best constant
of a parameter can do: a bound a learned policy of that parameter has to beat to have learned
anything about the features. A parameter left out gets no file and falls back to the fixed value
(B = 100, psi_K = e), as with trained tensors.

Exit status: 0 written, 2 bad input (a value outside the output's range, no value, a tensor file
already in the folder), reported as one line on stderr; nothing is written then.
"""

from __future__ import annotations

import argparse
import math
import shlex
import sys
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from lit_planner import planning, tensor_files
from lit_planner.errors import LitPlannerError, TensorFileError

EXIT_WRITTEN = 0
"""The tensors were written."""
EXIT_BAD_INPUT = 2
"""Nothing was written."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``lit tensors``."""
    commands = parser.add_subparsers(dest="tensors_command", metavar="ACTION", required=True)
    constant = commands.add_parser(
        "constant",
        help="write tensors that hold one value everywhere (a constant policy for lit bench)",
        description="Write b_tensor and/or k_tensor holding one value everywhere, with their "
        "sidecars. The tensor policy then plays that constant; a parameter left out falls back "
        "to the fixed value (B = 100, psi_K = e).",
    )
    low_b, high_b = _range("B")
    low_k, high_k = _range("psi_K")
    constant.add_argument("--b", type=float, metavar="B", help=f"batch size, {low_b:g}..{high_b:g}")
    constant.add_argument(
        "--psi-k", type=float, metavar="PSI", help=f"neighbour factor psi_K, {low_k:g}..{high_k:g}"
    )
    constant.add_argument(
        "--out", type=Path, required=True, metavar="DIR", help="folder to write into (created)"
    )


def run(args: argparse.Namespace) -> int:
    """Run ``lit tensors``; its exit status."""
    try:
        written = write_constant(args.out, args.b, args.psi_k, command=_command())
    except LitPlannerError as error:
        print(f"lit tensors: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    for output, path in written.items():
        print(f"lit tensors: {path}: {output} = {_value(args, output):g} everywhere")
    print(f"lit tensors: use them with --tensors {args.out} (lit bench, lit plan --policy tensor)")
    return EXIT_WRITTEN


def write_constant(
    folder: Path, b: float | None, psi_k: float | None, command: str | None = None
) -> dict[str, Path]:
    """Write a constant ``b_tensor`` (value ``b``) and/or ``k_tensor`` (``psi_k``) into
    ``folder``; returns the ``.npy`` paths written by output name.

    Raises:
        TensorFileError: no value, a value outside its output's range or not finite, or a tensor
            file or sidecar already in ``folder`` (checked before anything is written).
    """
    values = {output: value for output, value in (("B", b), ("psi_K", psi_k)) if value is not None}
    if not values:
        raise TensorFileError("give --b and/or --psi-k: the value(s) to write")
    for output, value in values.items():
        low, high = _range(output)
        if not (math.isfinite(value) and low <= value <= high):
            raise TensorFileError(f"{output} = {value:g} is outside its range {low:g}..{high:g}")
    if folder.exists() and not folder.is_dir():
        raise TensorFileError(f"{folder}: a file, not a folder")
    targets = {output: folder / planning.TENSOR_FILES[output] for output in values}
    for path in targets.values():
        for existing in (path, tensor_files.sidecar_path(path)):
            if existing.exists():
                raise TensorFileError(f"{existing}: already there; choose another --out")
    folder.mkdir(parents=True, exist_ok=True)
    created = datetime.now(UTC)
    for output, path in targets.items():
        tensor_files.write_tensor(
            path,
            np.full(tensor_files.TENSOR_SHAPE, values[output], dtype=tensor_files.TENSOR_DTYPE),
            output,
            provenance={"constant": values[output]} | ({"command": command} if command else {}),
            created=created,
        )
    return targets


def _command() -> str:
    return "lit " + shlex.join(sys.argv[1:])


def _value(args: argparse.Namespace, output: str) -> float:
    return float(args.b if output == "B" else args.psi_k)


def _range(output: str) -> tuple[float, float]:
    consequents = tensor_files.OUTPUTS[output].consequents
    return min(consequents), max(consequents)
