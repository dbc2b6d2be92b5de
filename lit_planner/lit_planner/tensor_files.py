"""Lookup-tensor files: ``<name>.npy`` (NPY v1.0, little-endian float32, C order) + ``<name>.json``.

The tensor holds the policy output z* on a node-centred grid with :data:`GRID_SIZE` points per
axis over [0, 1]: ``value[i, j, k] = z*(i / 100, j / 100, k / 100)`` with axes
(rho_global, rho_local, measure), before rounding. The sidecar follows the ``TensorSidecar`` schema
of ``lit_msgs_json``; its ``data_sha256`` is the SHA-256 of the data bytes (the .npy file after its
header).

:func:`lookup` is the Python reference of the lookup that the C++ reader must reproduce:

- inputs are clamped to [0, 1] (non-finite inputs are rejected) and scaled to ``f = x * 100.0`` in
  double precision;
- ``nearest`` takes node ``floor(f + 0.5)`` (half up);
- ``trilinear`` takes the cell ``i0 = min(floor(f), 99)``, ``t = f - i0`` and blends its 8 nodes
  with weights ``prod(t or 1 - t)``, in double precision from the float32 node values.
"""

from __future__ import annotations

import fcntl
import hashlib
import itertools
import math
import os
import shutil
import stat
import tempfile
import time
import tokenize
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

import lit_msgs_json
from lit_planner.errors import TensorFileError, TensorLookupError

Interpolation = Literal["nearest", "trilinear"]
Rounding = Literal["half_away_from_zero", "none"]

GRID_SIZE = 101
"""Nodes per axis; node i sits at i / (GRID_SIZE - 1)."""
AXIS_NAMES = ("rho_global", "rho_local", "measure")
"""Axis names in C order."""
TENSOR_SHAPE = (GRID_SIZE,) * len(AXIS_NAMES)
"""Shape of every lookup tensor."""
TENSOR_FILES = {"B": "b_tensor.npy", "psi_K": "k_tensor.npy"}
"""File name of each output's lookup tensor inside a tensor folder (sidecars: same stem, .json);
the planner's ``tensor`` policy looks for these and the learner exports them."""
TENSOR_DTYPE = np.dtype("<f4")
"""On-disk dtype: little-endian float32."""
SIDECAR_SCHEMA = "lit_msgs_json/TensorSidecar"
"""Schema name written into and required of every sidecar."""
SIDECAR_VERSION = 1
"""Sidecar schema version this module writes and reads."""
INTERPOLATIONS: tuple[Interpolation, ...] = ("nearest", "trilinear")
"""Supported lookup modes."""
DEFAULT_FUZZY_CENTRES = (0.0, 0.5, 1.0)
"""Membership centres of the learner's fuzzification (LEARNER.md)."""
DEFAULT_FUZZY_SIGMA = 0.2123
"""Membership width of the learner's fuzzification (LEARNER.md)."""
AFFINE_TEST_COEFFICIENTS = (20.0, 100.0, 50.0, 25.0)
"""(a, b, c, d) of the shared test tensor: every node is a multiple of 1/4 (exact in float32)
and the values span 20..195, inside B's range."""


@dataclass(frozen=True)
class OutputSpec:
    """A tensor output: its TSK consequents (whose extremes are its range) and rounding rule."""

    name: str
    """``B`` or ``psi_K``."""
    consequents: tuple[float, float, float]
    """Default zero-order TSK consequents f (LEARNER.md)."""
    rounding: Rounding
    """Rounding applied to a looked-up value before clamping it to the range."""


OUTPUTS: dict[str, OutputSpec] = {
    "B": OutputSpec("B", (20.0, 110.0, 200.0), "half_away_from_zero"),
    "psi_K": OutputSpec("psi_K", (3.0, 9.0, 15.0), "none"),
}
"""The two outputs a lookup tensor can hold."""


@dataclass(frozen=True)
class AxisSpec:
    """One tensor axis as the sidecar describes it."""

    name: str
    """Feature name: ``rho_global``, ``rho_local`` or ``measure``."""
    range: tuple[float, float]
    """Feature range covered by the nodes: (0, 1)."""
    size: int
    """Number of nodes."""
    transform: str
    """Feature transform before indexing: ``identity``."""


@dataclass(frozen=True)
class TensorSidecar:
    """The parsed, validated sidecar of a lookup tensor."""

    output: str
    """``B`` or ``psi_K``."""
    value_range: tuple[float, float]
    """[min, max] of the values (the consequents' extremes); executed values are clamped to it."""
    rounding: Rounding
    """Rounding of a looked-up value before clamping."""
    axes: tuple[AxisSpec, ...]
    """The three axes in C order."""
    interpolation: Interpolation
    """Default lookup mode."""
    fuzzy_centres: tuple[float, ...]
    """Gaussian membership centres the policy was trained with."""
    fuzzy_sigma: float
    """Gaussian membership width the policy was trained with."""
    tsk_consequents: tuple[float, ...]
    """Zero-order TSK consequents f."""
    reward: Mapping[str, Any]
    """Reward configuration of the training."""
    training: Mapping[str, Any]
    """Training configuration."""
    policy_version: int
    """Version of the policy that was exported."""
    data_sha256: str
    """SHA-256 of the .npy data bytes."""
    checkpoint_sha256: str | None
    """SHA-256 of the source checkpoint; None for synthetic tensors."""
    dtype: str
    """On-disk dtype, ``<f4``."""
    shape: tuple[int, ...]
    """Tensor shape."""
    created: str
    """Export time, ISO 8601."""
    provenance: Mapping[str, Any]
    """Free-form provenance."""
    path: Path | None = field(default=None, compare=False)
    """Sidecar file this was read from or written to."""

    def to_dict(self) -> dict[str, Any]:
        """The sidecar document (what :func:`from_dict` reads)."""
        return {
            "schema": SIDECAR_SCHEMA,
            "version": SIDECAR_VERSION,
            "output": {
                "name": self.output,
                "range": list(self.value_range),
                "rounding": self.rounding,
            },
            "axes": [
                {"name": a.name, "range": list(a.range), "size": a.size, "transform": a.transform}
                for a in self.axes
            ],
            "interpolation": self.interpolation,
            "fuzzification": {"centres": list(self.fuzzy_centres), "sigma": self.fuzzy_sigma},
            "tsk": {"consequents": list(self.tsk_consequents)},
            "reward": dict(self.reward),
            "training": dict(self.training),
            "policy_version": self.policy_version,
            "data_sha256": self.data_sha256,
            "checkpoint_sha256": self.checkpoint_sha256,
            "dtype": self.dtype,
            "shape": list(self.shape),
            "created": self.created,
            "provenance": dict(self.provenance),
        }

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any], path: Path | None = None) -> TensorSidecar:
        """Build from a document that already passed schema validation."""
        return cls(
            output=doc["output"]["name"],
            value_range=_pair(doc["output"]["range"]),
            rounding=doc["output"]["rounding"],
            axes=tuple(
                AxisSpec(a["name"], _pair(a["range"]), a["size"], a["transform"])
                for a in doc["axes"]
            ),
            interpolation=doc["interpolation"],
            fuzzy_centres=tuple(float(c) for c in doc["fuzzification"]["centres"]),
            fuzzy_sigma=float(doc["fuzzification"]["sigma"]),
            tsk_consequents=tuple(float(f) for f in doc["tsk"]["consequents"]),
            reward=doc["reward"],
            training=doc["training"],
            policy_version=doc["policy_version"],
            data_sha256=doc["data_sha256"],
            checkpoint_sha256=doc["checkpoint_sha256"],
            dtype=doc["dtype"],
            shape=tuple(doc["shape"]),
            created=doc["created"],
            provenance=doc["provenance"],
            path=path,
        )


def sidecar_path(path_npy: str | Path) -> Path:
    """The sidecar that belongs to ``path_npy``: same directory and stem, suffix ``.json``.

    Raises:
        TensorFileError: ``path_npy`` does not end in ``.npy``.
    """
    path = Path(path_npy)
    if path.suffix != ".npy":
        raise TensorFileError(f"{path}: a lookup tensor file must end in .npy")
    return path.with_suffix(".json")


def write_tensor(
    path_npy: str | Path,
    values: ArrayLike,
    output: str,
    *,
    interpolation: Interpolation = "trilinear",
    consequents: Sequence[float] | None = None,
    fuzzy_centres: Sequence[float] = DEFAULT_FUZZY_CENTRES,
    fuzzy_sigma: float = DEFAULT_FUZZY_SIGMA,
    reward: Mapping[str, Any] | None = None,
    training: Mapping[str, Any] | None = None,
    policy_version: int = 0,
    checkpoint_sha256: str | None = None,
    provenance: Mapping[str, Any] | None = None,
    created: datetime | None = None,
) -> TensorSidecar:
    """Write ``values`` as ``path_npy`` and its validated sidecar ``<stem>.json`` beside it.

    Args:
        path_npy: target ``.npy`` path; the sidecar goes to the same stem with ``.json``.
        values: array of shape :data:`TENSOR_SHAPE`, finite, inside [min f, max f] once stored as
            float32 (clip before writing if the network's arithmetic overshoots by an ulp).
        output: ``B`` or ``psi_K``.
        interpolation: default lookup mode recorded in the sidecar.
        consequents: TSK consequents; the output's defaults (:data:`OUTPUTS`) when None.
        fuzzy_centres, fuzzy_sigma: fuzzification constants the policy was trained with.
        reward, training, provenance: configuration and provenance objects (JSON-able).
        policy_version: version of the exported policy.
        checkpoint_sha256: SHA-256 of the source checkpoint, None for synthetic tensors.
        created: export time (timezone-aware); now (UTC) when None.

    Returns:
        The sidecar as written.

    Raises:
        TensorFileError: bad path, output, shape, non-finite or out-of-range values, or a sidecar
            that fails the schema; nothing is written in those cases.
    """
    path = Path(path_npy)
    side = sidecar_path(path)
    if output not in OUTPUTS:
        raise TensorFileError(
            f"{path}: unknown output {output!r}; expected one of {sorted(OUTPUTS)}"
        )
    spec = OUTPUTS[output]
    f = tuple(float(v) for v in (spec.consequents if consequents is None else consequents))
    if not f or min(f) >= max(f):
        raise TensorFileError(f"{path}: consequents {f} do not span a range")
    data = np.ascontiguousarray(np.asarray(values), dtype=TENSOR_DTYPE)
    _check_values(path, data, TENSOR_SHAPE, (min(f), max(f)))
    stamp = created or datetime.now(UTC)
    if stamp.tzinfo is None:
        raise TensorFileError(f"{path}: created time {stamp.isoformat()} has no time zone")
    sidecar = TensorSidecar(
        output=output,
        value_range=(min(f), max(f)),
        rounding=spec.rounding,
        axes=tuple(AxisSpec(name, (0.0, 1.0), GRID_SIZE, "identity") for name in AXIS_NAMES),
        interpolation=interpolation,
        fuzzy_centres=tuple(float(c) for c in fuzzy_centres),
        fuzzy_sigma=float(fuzzy_sigma),
        tsk_consequents=f,
        reward=dict(reward or {}),
        training=dict(training or {}),
        policy_version=policy_version,
        data_sha256=hashlib.sha256(data.tobytes()).hexdigest(),
        checkpoint_sha256=checkpoint_sha256,
        dtype=TENSOR_DTYPE.str,
        shape=TENSOR_SHAPE,
        created=stamp.isoformat(timespec="seconds"),
        provenance=dict(provenance or {}),
        path=side,
    )
    try:
        text = lit_msgs_json.dumps(SIDECAR_SCHEMA, sidecar.to_dict(), indent=2)
    except (
        lit_msgs_json.SchemaError,
        TypeError,
    ) as exc:  # TypeError: a value that is not JSON-able
        raise TensorFileError(f"{side}: sidecar not written: {exc}") from exc
    with path.open("wb") as stream:
        np.lib.format.write_array(stream, data, version=(1, 0), allow_pickle=False)
    side.write_text(text + "\n", encoding="utf-8")
    return sidecar


STAGE_PREFIX = ".staged-"
"""Names of :func:`staged_folder`'s folders: ``.staged-<random>``."""


def held_new(create: Callable[[], Path]) -> tuple[Path, int]:
    """A new file or folder made by ``create`` (which returns its path), and a descriptor of it
    that holds its ``flock``: the sign to :func:`remove_unheld` that a process still writes it.
    Another process's clean-up can come between the creation and the lock; it takes the lock
    itself before it removes (:func:`remove_unheld`), so the lock taken here is on the removed
    entry, seen here as such, and ``create`` makes another. (Locked only after it was checked,
    an entry removed in that gap left the writer writing into nothing.) An entry that cannot be
    locked is removed, and the error goes on."""
    while True:
        path = create()
        try:
            descriptor = _open_to_lock(path)
        except FileNotFoundError:
            continue  # removed before it could be opened
        except BaseException:
            _discard(path)
            raise
        try:
            fcntl.flock(descriptor, fcntl.LOCK_EX)
            if os.path.samestat(os.fstat(descriptor), os.stat(path)):  # links followed, as opened
                return path, descriptor
        except FileNotFoundError:
            pass  # removed while the lock was awaited
        except BaseException:
            os.close(descriptor)
            _discard(path)
            raise
        os.close(descriptor)


def remove_unheld(path: Path) -> bool:
    """Remove the file or folder ``path`` unless a process holds its ``flock`` (a writer's own
    temporary entry: :func:`held_new`); whether it was removed. The lock is taken here for the
    removal, so a writer that locks its brand-new entry meanwhile finds it removed. An entry
    that cannot be opened or locked (a link, another user's, a lock the file system refuses) is
    left alone."""
    try:
        descriptor = _open_to_lock(path, follow=False)
    except OSError:
        return False  # gone meanwhile, or a link: not a writer's
    try:
        fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
        if not os.path.samestat(os.fstat(descriptor), os.lstat(path)):
            return False  # replaced since it was opened
        if stat.S_ISDIR(os.fstat(descriptor).st_mode):
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
        return True
    except OSError:  # held (BlockingIOError), gone, or not lockable here
        return False
    finally:
        os.close(descriptor)  # and with it the lock taken here


def _open_to_lock(path: Path, follow: bool = True) -> int:
    """A descriptor of ``path`` that an exclusive ``flock`` can be taken on: a file's is opened
    for writing, which NFS needs (it emulates flock with a byte-range lock), a folder's for
    reading (the only way a folder opens)."""
    no_follow = 0 if follow else os.O_NOFOLLOW
    is_folder = os.path.isdir(path) if follow else stat.S_ISDIR(os.lstat(path).st_mode)
    mode = os.O_RDONLY | os.O_DIRECTORY if is_folder else os.O_RDWR
    return os.open(path, mode | os.O_CLOEXEC | no_follow)


def _discard(path: Path) -> None:
    """Remove an entry :func:`held_new` made and could not lock (errors ignored)."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


def stale_stages(directory: Path) -> list[Path]:
    """The staging folders of :func:`staged_folder` in ``directory`` that no export holds: one
    killed (SIGKILL, a power cut) before its end left them, and they kept the folder from
    counting as empty, which refused the export's own retry. An export holds a lock on its
    staging folder while it writes (``flock``: released by the kernel when the process ends,
    whatever its process id becomes), so a folder whose lock can be taken is stale."""
    return [entry for entry in _stages(directory) if not lock_held(entry)]


def holds_files(directory: Path) -> bool:
    """Whether the folder ``directory`` holds anything besides :func:`stale_stages`."""
    stale = set(stale_stages(directory))
    return any(entry not in stale for entry in directory.iterdir())


def lock_held(path: Path) -> bool:
    """Whether a process holds an ``flock`` on ``path`` (a file or folder that its writer locks
    while it writes: an export's staging folder, a checkpoint's temporary file)."""
    try:
        descriptor = _open_to_lock(path)
    except OSError:
        return False  # gone meanwhile
    try:
        fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    except OSError:
        return False  # no lock on this file system: nobody holds one either
    finally:
        os.close(descriptor)  # and with it a lock this took
    return False


EXPORT_WAIT = 30.0
"""Seconds :func:`wait_for_exports` waits at most for the exports writing a folder."""


def wait_for_exports(directory: Path, timeout: float = EXPORT_WAIT) -> bool:
    """Wait until no export holds a staging folder of :func:`staged_folder` in ``directory``
    (its writes and its renames are done), for ``timeout`` seconds at most; whether one was
    held and ended within it. A reader whose files disagree (a new sidecar beside the old
    tensor) reads them again when this is True: the export was between its renames."""
    held = [entry for entry in _stages(directory) if lock_held(entry)]
    deadline = time.monotonic() + timeout
    for stage in held:
        while lock_held(stage):
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.02)
    return bool(held)


def _stages(directory: Path) -> list[Path]:
    """The staging folders of :func:`staged_folder` in ``directory`` (none if it is not a folder)."""
    if not directory.is_dir():
        return []
    return [
        entry
        for entry in directory.iterdir()
        if entry.name.startswith(STAGE_PREFIX) and entry.is_dir()
    ]


@contextmanager
def staged_folder(directory: Path, remove: Sequence[str] = ()) -> Iterator[Path]:
    """A staging folder inside ``directory`` (created if needed) for files that replace those of
    the same names in ``directory``, one rename each, once the block has written them all: a
    reader of ``directory`` sees each file whole, and a block that fails (a full disk) leaves
    nothing of itself. The files named in ``remove`` go from ``directory`` just before the
    renames (a failure there also leaves nothing of the block). The staging folder goes in any
    case, and ``directory`` too on an error if it was created here; the error goes on (OSError
    for a folder that cannot be made). Staging folders that killed processes left there
    (:func:`stale_stages`) are removed first."""
    created = not directory.exists()
    directory.mkdir(parents=True, exist_ok=True)
    try:
        for stale in _stages(directory):
            remove_unheld(stale)
        # Locked while this export writes (stale_stages), from before anything is written.
        stage, lock = held_new(lambda: Path(tempfile.mkdtemp(prefix=STAGE_PREFIX, dir=directory)))
        try:
            yield stage
            for name in remove:
                (directory / name).unlink(missing_ok=True)
            for item in sorted(stage.iterdir()):
                os.replace(item, directory / item.name)
        finally:
            shutil.rmtree(stage, ignore_errors=True)
            os.close(lock)
    except BaseException:
        if created:
            shutil.rmtree(directory, ignore_errors=True)
        raise


MAX_SIDECAR_BYTES = 1 << 20
"""The largest sidecar read (those written are about 2 KB)."""


def read_sidecar_bytes(side: Path) -> bytes:
    """The bytes of the sidecar ``side``: a regular file (links followed) of at most
    :data:`MAX_SIDECAR_BYTES`. Opened without blocking and checked before it is read: a named
    pipe in its place held the planner node's reading thread (and every later query) for good,
    and a link to ``/dev/zero`` read until memory ran out.

    Raises:
        TensorFileError: it cannot be opened, is not a regular file, or is larger.
    """
    try:
        descriptor = os.open(side, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as error:
        raise TensorFileError(f"{side}: cannot be read ({error.strerror})") from None
    with os.fdopen(descriptor, "rb") as stream:
        if not stat.S_ISREG(os.fstat(descriptor).st_mode):
            raise TensorFileError(f"{side}: not a regular file (a pipe, device or folder?)")
        data = stream.read(MAX_SIDECAR_BYTES + 1)
    if len(data) > MAX_SIDECAR_BYTES:
        raise TensorFileError(f"{side}: larger than {MAX_SIDECAR_BYTES} bytes: not a sidecar")
    return data


def read_sidecar(path_npy: str | Path) -> TensorSidecar:
    """Read and validate the sidecar that sits next to ``path_npy``.

    Raises:
        TensorFileError: the .npy or its sidecar is missing, the sidecar is not JSON, fails the
            schema, or its output range disagrees with its consequents.
    """
    path = Path(path_npy)
    side = sidecar_path(path)
    if not path.is_file():
        raise TensorFileError(f"{path}: tensor file not found")
    if not (side.exists() or side.is_symlink()):  # anything else there: read_sidecar_bytes says
        raise TensorFileError(f"{path}: no sidecar next to it (expected {side})")
    try:
        doc = lit_msgs_json.loads(SIDECAR_SCHEMA, read_sidecar_bytes(side))
    except lit_msgs_json.SchemaError as exc:
        raise TensorFileError(f"{side}: {exc}") from exc
    sidecar = TensorSidecar.from_dict(doc, side)
    lo, hi = sidecar.value_range
    if not lo < hi or (lo, hi) != (min(sidecar.tsk_consequents), max(sidecar.tsk_consequents)):
        raise TensorFileError(
            f"{side}: $.output.range {[lo, hi]} must be the increasing [min, max] of "
            f"$.tsk.consequents {list(sidecar.tsk_consequents)}"
        )
    return sidecar


def read_tensor(path_npy: str | Path) -> tuple[NDArray[np.float32], TensorSidecar]:
    """Read a lookup tensor with every check the C++ reader makes, plus the data hash.

    Returns:
        The read-only float32 values and their sidecar.

    Raises:
        TensorFileError: bad sidecar (see :func:`read_sidecar`), not NPY v1.0, wrong dtype, Fortran
            order, shape differing from the sidecar, truncated or trailing data, hash mismatch,
            non-finite or out-of-range values.
    """
    sidecar = read_sidecar(path_npy)
    path = Path(path_npy)
    with path.open("rb") as stream:
        try:
            version = np.lib.format.read_magic(stream)
            header = np.lib.format.read_array_header_1_0(stream) if version == (1, 0) else None
        except (ValueError, SyntaxError, tokenize.TokenError) as exc:  # numpy parses a dict literal
            raise TensorFileError(f"{path}: not a valid NPY file: {exc}") from exc
        if header is None:
            raise TensorFileError(f"{path}: NPY version {version[0]}.{version[1]}, expected 1.0")
        shape, fortran_order, dtype = header
        payload = stream.read()
    if dtype != TENSOR_DTYPE:
        raise TensorFileError(f"{path}: dtype {dtype.str}, expected {TENSOR_DTYPE.str}")
    if fortran_order:
        raise TensorFileError(f"{path}: Fortran order, expected C order")
    if tuple(shape) != sidecar.shape:
        raise TensorFileError(
            f"{path}: shape {tuple(shape)} differs from the sidecar's {sidecar.shape}"
        )
    expected_bytes = math.prod(shape) * TENSOR_DTYPE.itemsize
    if len(payload) != expected_bytes:
        raise TensorFileError(f"{path}: {len(payload)} data bytes, expected {expected_bytes}")
    digest = hashlib.sha256(payload).hexdigest()
    if digest != sidecar.data_sha256:
        raise TensorFileError(
            f"{path}: data SHA-256 {digest} differs from the sidecar's {sidecar.data_sha256}"
        )
    values = np.frombuffer(payload, dtype=TENSOR_DTYPE).reshape(shape)
    _check_values(path, values, sidecar.shape, sidecar.value_range)
    return values, sidecar


def lookup(
    values: ArrayLike, x: ArrayLike, mode: Interpolation = "trilinear"
) -> NDArray[np.float64]:
    """Reference lookup of feature points ``x`` in a node-centred tensor over [0, 1]^3.

    Args:
        values: tensor of shape (s0, s1, s2), each s >= 2; node i of an axis sits at i / (s - 1).
        x: finite feature points, shape (..., 3); clamped to [0, 1].
        mode: ``nearest`` (index ``floor(x * (s - 1) + 0.5)``, half up) or ``trilinear``.

    Returns:
        float64 array of shape ``x.shape[:-1]`` (0-d for a single point).

    Raises:
        TensorLookupError: malformed tensor, non-finite or wrongly shaped points, unknown mode.
    """
    grid = np.asarray(values)
    if grid.ndim != 3 or min(grid.shape) < 2:
        raise TensorLookupError(
            f"tensor of shape {grid.shape} is not 3-D with at least 2 nodes per axis"
        )
    points = np.asarray(x, dtype=np.float64)
    if points.ndim == 0 or points.shape[-1] != 3:
        raise TensorLookupError(
            f"feature points of shape {points.shape} do not end in an axis of 3"
        )
    if not np.all(np.isfinite(points)):
        raise TensorLookupError(
            f"feature points must be finite, got {points[~np.isfinite(points)][:3]}"
        )
    last = np.array(grid.shape) - 1
    scaled = np.clip(points, 0.0, 1.0) * last
    if mode == "nearest":
        index = np.floor(scaled + 0.5).astype(np.intp)
        nearest: NDArray[np.float64] = grid[index[..., 0], index[..., 1], index[..., 2]].astype(
            np.float64
        )
        return nearest
    if mode != "trilinear":
        raise TensorLookupError(f"unknown lookup mode {mode!r}; expected one of {INTERPOLATIONS}")
    base = np.minimum(np.floor(scaled).astype(np.intp), last - 1)
    t = scaled - base
    result = np.zeros(points.shape[:-1])
    for corner in itertools.product((0, 1), repeat=3):
        weight = np.prod(
            [t[..., a] if c else 1.0 - t[..., a] for a, c in enumerate(corner)], axis=0
        )
        node = grid[tuple(base[..., a] + c for a, c in enumerate(corner))]
        result += weight * node.astype(np.float64)
    return result


def affine_test_tensor(a: float, b: float, c: float, d: float) -> NDArray[np.float32]:
    """Tensor with ``value[i, j, k] = a + b*i/100 + c*j/100 + d*k/100`` (float32).

    Trilinear interpolation reproduces an affine function exactly, so the lookup of any point is
    known in closed form: the shared check between the Python and C++ readers.
    """
    i, j, k = np.meshgrid(*(np.arange(GRID_SIZE, dtype=np.float64),) * 3, indexing="ij")
    last = GRID_SIZE - 1
    return (a + b * i / last + c * j / last + d * k / last).astype(TENSOR_DTYPE)


def _pair(values: Sequence[float]) -> tuple[float, float]:
    return float(values[0]), float(values[1])


def _check_values(
    path: Path,
    values: NDArray[np.float32],
    shape: tuple[int, ...],
    value_range: tuple[float, float],
) -> None:
    if values.shape != shape:
        raise TensorFileError(f"{path}: values of shape {values.shape}, expected {shape}")
    finite = np.isfinite(values)
    if not finite.all():
        where = tuple(int(v) for v in np.argwhere(~finite)[0])
        raise TensorFileError(f"{path}: non-finite value {values[where]} at index {where}")
    lo, hi = value_range
    outside = (values < lo) | (values > hi)
    if outside.any():
        where = tuple(int(v) for v in np.argwhere(outside)[0])
        raise TensorFileError(
            f"{path}: value {values[where]} at index {where} outside the range [{lo}, {hi}]"
        )
