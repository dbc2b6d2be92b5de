"""Tests of lookup-tensor files: writing, strict reading, the sidecar, and the reference lookup."""

from __future__ import annotations

import hashlib
import json
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest
from lit_planner.errors import TensorFileError, TensorLookupError

import lit_msgs_json
from lit_planner import tensor_files as tf

CREATED = datetime(2026, 5, 9, 7, 35, tzinfo=UTC)
RNG_SEED = 20260509


@pytest.fixture
def b_tensor(tmp_path: Path) -> Path:
    path = tmp_path / "b_policy.npy"
    tf.write_tensor(
        path,
        tf.affine_test_tensor(*tf.AFFINE_TEST_COEFFICIENTS),
        "B",
        created=CREATED,
        reward={"w_t": 0.01},
        training={"episodes": 3},
        policy_version=4,
        provenance={"note": "affine test tensor"},
    )
    return path


def rewrite_sidecar(npy: Path, **changes: object) -> None:
    side = npy.with_suffix(".json")
    doc = json.loads(side.read_text())
    doc.update(changes)
    side.write_text(json.dumps(doc))


def test_write_read_round_trip(b_tensor: Path) -> None:
    values, sidecar = tf.read_tensor(b_tensor)
    assert np.array_equal(values, tf.affine_test_tensor(*tf.AFFINE_TEST_COEFFICIENTS))
    assert values.dtype == np.dtype("<f4") and values.shape == (101, 101, 101)
    assert not values.flags.writeable
    assert sidecar.path == b_tensor.parent / "b_policy.json"
    assert (sidecar.output, sidecar.value_range, sidecar.rounding) == (
        "B",
        (20.0, 200.0),
        "half_away_from_zero",
    )
    assert [a.name for a in sidecar.axes] == ["rho_global", "rho_local", "measure"]
    assert sidecar.policy_version == 4 and sidecar.checkpoint_sha256 is None
    assert sidecar.created == "2026-05-09T07:35:00+00:00"
    assert sidecar == tf.read_sidecar(b_tensor)
    # The hash covers exactly the data bytes at the end of the file, independently recomputed.
    raw = b_tensor.read_bytes()
    assert raw[:8] == b"\x93NUMPY\x01\x00"
    assert sidecar.data_sha256 == hashlib.sha256(raw[-(101**3) * 4 :]).hexdigest()
    lit_msgs_json.validate("TensorSidecar", json.loads(sidecar.path.read_text()))


def test_module_constants_agree_with_the_schema() -> None:
    schema = lit_msgs_json.load_schema("TensorSidecar")
    props = schema["properties"]
    assert tuple(props["shape"]["const"]) == tf.TENSOR_SHAPE
    assert props["dtype"]["const"] == tf.TENSOR_DTYPE.str
    assert props["schema"]["const"] == tf.SIDECAR_SCHEMA
    assert props["version"]["const"] == tf.SIDECAR_VERSION
    assert tuple(props["interpolation"]["enum"]) == tf.INTERPOLATIONS
    assert set(props["output"]["properties"]["name"]["enum"]) == set(tf.OUTPUTS)
    names = [item["properties"]["name"]["const"] for item in props["axes"]["prefixItems"]]
    assert tuple(names) == tf.AXIS_NAMES
    assert schema["$defs"]["axis"]["properties"]["size"]["const"] == tf.GRID_SIZE


def test_psi_k_tensor(tmp_path: Path) -> None:
    path = tmp_path / "k.npy"
    tf.write_tensor(
        path,
        tf.affine_test_tensor(3.0, 4.0, 4.0, 4.0),
        "psi_K",
        interpolation="nearest",
        checkpoint_sha256="ab" * 32,
    )
    _, sidecar = tf.read_tensor(path)
    assert (sidecar.value_range, sidecar.rounding, sidecar.interpolation) == (
        (3.0, 15.0),
        "none",
        "nearest",
    )
    assert sidecar.tsk_consequents == (3.0, 9.0, 15.0) and sidecar.checkpoint_sha256 == "ab" * 32


@pytest.mark.parametrize(
    ("values", "output", "kwargs", "message"),
    [
        (
            np.full((101, 101, 100), 50.0),
            "B",
            {},
            r"values of shape \(101, 101, 100\), expected \(101, 101, 101\)",
        ),
        (
            np.full((101, 101, 101), 201.0),
            "B",
            {},
            r"value 201\.0 at index \(0, 0, 0\) outside the range \[20\.0, 200\.0\]",
        ),
        (
            np.full((101, 101, 101), 16.0),
            "psi_K",
            {},
            r"value 16\.0 at index \(0, 0, 0\) outside the range \[3\.0, 15\.0\]",
        ),
        (np.full((101, 101, 101), np.nan), "B", {}, r"non-finite value nan at index \(0, 0, 0\)"),
        (np.full((101, 101, 101), 50.0), "K", {}, r"unknown output 'K'"),
        (
            np.full((101, 101, 101), 50.0),
            "B",
            {"checkpoint_sha256": "xyz"},
            r"\$\.checkpoint_sha256",
        ),
        (np.full((101, 101, 101), 50.0), "B", {"fuzzy_sigma": -1.0}, r"\$\.fuzzification\.sigma"),
        (
            np.full((101, 101, 101), 50.0),
            "B",
            {"consequents": (5.0, 5.0, 5.0)},
            r"do not span a range",
        ),
        (
            np.full((101, 101, 101), 50.0),
            "B",
            {"created": datetime(2026, 1, 1)},
            r"has no time zone",
        ),
        (np.full((101, 101, 101), 50.0), "B", {"reward": {"f": object()}}, r"sidecar not written"),
    ],
)
def test_write_rejects_bad_input_and_writes_nothing(
    tmp_path: Path, values: np.ndarray, output: str, kwargs: dict[str, object], message: str
) -> None:
    path = tmp_path / "bad.npy"
    with pytest.raises(TensorFileError, match=message) as info:
        tf.write_tensor(path, values, output, **kwargs)  # type: ignore[arg-type]
    assert "bad." in str(info.value)
    assert not path.exists() and not path.with_suffix(".json").exists()


def test_write_rejects_a_path_without_npy_suffix(tmp_path: Path) -> None:
    with pytest.raises(TensorFileError, match=r"b\.bin: a lookup tensor file must end in \.npy"):
        tf.write_tensor(
            tmp_path / "b.bin", tf.affine_test_tensor(*tf.AFFINE_TEST_COEFFICIENTS), "B"
        )


def test_read_sidecar_requires_both_files(tmp_path: Path, b_tensor: Path) -> None:
    b_tensor.with_suffix(".json").rename(tmp_path / "elsewhere.json")
    with pytest.raises(
        TensorFileError, match=r"b_policy\.npy: no sidecar next to it \(expected .*b_policy\.json\)"
    ):
        tf.read_sidecar(b_tensor)
    with pytest.raises(TensorFileError, match=r"missing\.npy: tensor file not found"):
        tf.read_sidecar(tmp_path / "missing.npy")


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (
            {"output": {"name": "C", "range": [20, 200], "rounding": "none"}},
            r"\$\.output\.name: 'C' is not one of",
        ),
        ({"shape": [101, 101, 100]}, r"\$\.shape: .*\(rule: const\)"),
        ({"data_sha256": "0" * 63}, r"\$\.data_sha256: .*\(rule: pattern\)"),
        (
            {"output": {"name": "B", "range": [20, 190], "rounding": "half_away_from_zero"}},
            (
                r"\$\.output\.range \[20\.0, 190\.0\] must be the increasing \[min, max\] "
                r"of \$\.tsk\.consequents"
            ),
        ),
    ],
)
def test_read_sidecar_names_file_and_field(
    b_tensor: Path, changes: dict[str, object], message: str
) -> None:
    rewrite_sidecar(b_tensor, **changes)
    with pytest.raises(TensorFileError, match=message) as info:
        tf.read_sidecar(b_tensor)
    assert str(info.value).startswith(str(b_tensor.with_suffix(".json")))


def test_read_sidecar_rejects_nan_text(b_tensor: Path) -> None:
    side = b_tensor.with_suffix(".json")
    side.write_text(side.read_text().replace("0.2123", "NaN"))
    with pytest.raises(TensorFileError, match=r"b_policy\.json: .*NaN is not allowed"):
        tf.read_sidecar(b_tensor)


def test_read_tensor_detects_tampered_data(b_tensor: Path) -> None:
    raw = bytearray(b_tensor.read_bytes())
    raw[-1] ^= 0x01
    b_tensor.write_bytes(bytes(raw))
    with pytest.raises(
        TensorFileError,
        match=r"b_policy\.npy: data SHA-256 [0-9a-f]{64} differs from the sidecar's",
    ):
        tf.read_tensor(b_tensor)


@pytest.mark.parametrize(
    ("replace", "message"),
    [
        (lambda p: np.save(p, np.full((101, 101, 101), 50.0)), r"dtype <f8, expected <f4"),
        (
            lambda p: np.save(p, np.full((101, 101, 101), 50.0, dtype=">f4")),
            r"dtype >f4, expected <f4",
        ),
        (
            lambda p: np.save(p, np.asfortranarray(np.full((101, 101, 101), 50.0, dtype="<f4"))),
            r"Fortran order",
        ),
        (
            lambda p: np.save(p, np.full((101, 101, 100), 50.0, dtype="<f4")),
            r"shape \(101, 101, 100\) differs",
        ),
        (lambda p: p.write_bytes(p.read_bytes()[:-4]), r"4121200 data bytes, expected 4121204"),
        (lambda p: p.write_bytes(b"not an npy file at all"), r"not a valid NPY file"),
        # header edits that keep its length: numpy raised a tokenize.TokenError for the second
        (lambda p: _edit_header(p, b"(101, 101, 101)", b"(101, abc, 101)"), r"not a valid NPY"),
        (lambda p: _edit_header(p, b"}", b" "), r"not a valid NPY file"),
        (lambda p: _save_v2(p), r"NPY version 2\.0, expected 1\.0"),
    ],
)
def test_read_tensor_checks_like_the_cpp_reader(b_tensor: Path, replace, message: str) -> None:  # type: ignore[no-untyped-def]
    replace(b_tensor)
    with pytest.raises(TensorFileError, match=message) as info:
        tf.read_tensor(b_tensor)
    assert str(info.value).startswith(str(b_tensor))


def test_read_tensor_checks_range_even_when_hash_matches(b_tensor: Path) -> None:
    values = np.full((101, 101, 101), 250.0, dtype="<f4")
    np.save(b_tensor, values)
    rewrite_sidecar(b_tensor, data_sha256=hashlib.sha256(values.tobytes()).hexdigest())
    with pytest.raises(
        TensorFileError, match=r"value 250\.0 at index \(0, 0, 0\) outside the range"
    ):
        tf.read_tensor(b_tensor)


def _edit_header(path: Path, old: bytes, new: bytes) -> None:
    data = path.read_bytes()
    assert len(old) == len(new) and data.index(old) < 128  # in the header, its length kept
    path.write_bytes(data.replace(old, new, 1))


def _save_v2(path: Path) -> None:
    with path.open("wb") as stream:
        np.lib.format.write_array(stream, np.zeros((101, 101, 101), dtype="<f4"), version=(2, 0))


def affine(coefficients: tuple[float, float, float, float], x: np.ndarray) -> np.ndarray:
    a, b, c, d = coefficients
    return a + b * x[..., 0] + c * x[..., 1] + d * x[..., 2]


def test_affine_tensor_values() -> None:
    values = tf.affine_test_tensor(1.0, 2.0, 3.0, 4.0)
    assert values.dtype == np.dtype("<f4") and values.shape == tf.TENSOR_SHAPE
    assert values[0, 0, 0] == 1.0 and values[100, 100, 100] == 10.0
    assert values[50, 0, 0] == 2.0 and values[0, 50, 0] == 2.5 and values[0, 0, 50] == 3.0
    shared = tf.affine_test_tensor(*tf.AFFINE_TEST_COEFFICIENTS)
    assert shared.min() == 20.0 and shared.max() == 195.0
    assert np.array_equal(shared * 4, np.round(shared * 4))  # multiples of 1/4: exact in float32


def test_trilinear_reproduces_the_affine_function() -> None:
    rng = np.random.default_rng(RNG_SEED)
    x = rng.uniform(0.0, 1.0, (1000, 3))
    exact = tf.AFFINE_TEST_COEFFICIENTS
    got = tf.lookup(tf.affine_test_tensor(*exact), x, "trilinear")
    assert got.shape == (1000,) and got.dtype == np.float64
    assert np.max(np.abs(got - affine(exact, x))) < 1e-9
    # Coefficients that float32 cannot hold exactly: equal up to the nodes' float32 rounding.
    inexact = (3.0, 1.7, -2.2, 0.9)
    got = tf.lookup(tf.affine_test_tensor(*inexact), x, "trilinear")
    assert np.max(np.abs(got - affine(inexact, x))) < 1e-5


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_trilinear_blends_only_the_enclosing_cell(axis: int) -> None:
    # A quadratic along one axis: any other cell (or extrapolation) would give another value.
    node = np.arange(101, dtype=np.float64) ** 2
    values = np.broadcast_to(
        node.reshape([-1 if a == axis else 1 for a in range(3)]), tf.TENSOR_SHAPE
    )
    x = np.random.default_rng(RNG_SEED + axis).uniform(0, 1, (200, 3))
    x[:3, axis] = [0.127, 0.995, 1.0]
    f = x[:, axis] * 100
    i0 = np.minimum(np.floor(f), 99).astype(int)
    expected = node[i0] + (f - i0) * (node[i0 + 1] - node[i0])
    assert np.allclose(tf.lookup(values, x, "trilinear"), expected, rtol=0, atol=1e-9)


def test_lookup_at_grid_nodes() -> None:
    values = tf.affine_test_tensor(3.0, 1.7, -2.2, 0.9)
    nodes = np.random.default_rng(RNG_SEED).integers(0, 101, (500, 3))
    expected = values[nodes[:, 0], nodes[:, 1], nodes[:, 2]].astype(np.float64)
    assert np.array_equal(tf.lookup(values, nodes / 100, "nearest"), expected)
    # i / 100 * 100 is not always i in binary (0.29 * 100 = 28.999999999999996): trilinear then
    # blends in a neighbour with a weight of about 1e-15.
    assert np.max(np.abs(tf.lookup(values, nodes / 100, "trilinear") - expected)) < 1e-12
    exact_nodes = np.array([[0.0, 0.5, 1.0], [0.25, 0.75, 0.0]])  # x * 100 exact in binary
    expected = values[[0, 25], [50, 75], [100, 0]].astype(np.float64)
    assert np.array_equal(tf.lookup(values, exact_nodes, "trilinear"), expected)


def test_nearest_rounds_half_up_and_clamps() -> None:
    values = tf.affine_test_tensor(*tf.AFFINE_TEST_COEFFICIENTS)  # 20 + i + j/2 + k/4
    x = np.array([[0.125, 0.375, 0.625], [0.12, 0.374, 0.626], [-1.0, 2.0, 0.5], [1.0, 1.0, 1.0]])
    got = tf.lookup(values, x, "nearest")
    assert got.tolist() == [
        20 + 13 + 38 / 2 + 63 / 4,
        20 + 12 + 37 / 2 + 63 / 4,
        20 + 0 + 50 + 12.5,
        195.0,
    ]
    assert float(tf.lookup(values, [0.3, 0.2, 0.1], "nearest")) == 20 + 30 + 10 + 2.5
    assert float(tf.lookup(values, [-5.0, 0.0, 0.0], "trilinear")) == 20.0
    assert float(tf.lookup(values, [5.0, 5.0, 5.0], "trilinear")) == 195.0


def test_lookup_keeps_batch_shape() -> None:
    values = tf.affine_test_tensor(*tf.AFFINE_TEST_COEFFICIENTS)
    x = np.random.default_rng(RNG_SEED).uniform(0, 1, (4, 6, 3))
    assert tf.lookup(values, x, "nearest").shape == (4, 6)
    assert tf.lookup(values, x[0, 0], "trilinear").shape == ()


@pytest.mark.parametrize(
    ("values", "x", "mode", "message"),
    [
        (
            np.zeros((101, 101, 101)),
            [0.5, np.nan, 0.5],
            "nearest",
            r"feature points must be finite",
        ),
        (
            np.zeros((101, 101, 101)),
            [0.5, 0.5],
            "nearest",
            r"feature points of shape \(2,\) do not end in an axis of 3",
        ),
        (np.zeros((101, 101, 101)), [0.5, 0.5, 0.5], "cubic", r"unknown lookup mode 'cubic'"),
        (
            np.zeros((101, 101)),
            [0.5, 0.5, 0.5],
            "nearest",
            r"tensor of shape \(101, 101\) is not 3-D",
        ),
    ],
)
def test_lookup_rejects_bad_input(
    values: np.ndarray, x: list[float], mode: str, message: str
) -> None:
    with pytest.raises(TensorLookupError, match=message):
        tf.lookup(values, x, mode)  # type: ignore[arg-type]


def test_what_a_killed_export_left_does_not_block_its_retry(tmp_path: Path) -> None:
    """An export killed mid-way (SIGKILL) left DIR/.staged-*, and the retry into DIR was refused
    as "exists and is not empty". Staging folders no export holds no longer count, and the next
    export removes them; one an export is writing still counts."""
    import signal
    import subprocess
    import sys

    from lit_planner import bag

    folder = tmp_path / "export"
    # An export that is killed while it writes into its staging folder.
    export = (
        "import sys, time\n"
        "from pathlib import Path\n"
        "from lit_planner import tensor_files\n"
        "with tensor_files.staged_folder(Path(sys.argv[1])) as stage:\n"
        "    (stage / 'checkpoint.pt').write_bytes(b'half')\n"
        "    print('writing', flush=True)\n"
        "    time.sleep(600)\n"
    )
    writer = subprocess.Popen(
        [sys.executable, "-c", export, str(folder)], stdout=subprocess.PIPE, text=True
    )
    try:
        assert writer.stdout is not None and writer.stdout.readline() == "writing\n"
        (stage,) = folder.iterdir()
        assert tf.stale_stages(folder) == [] and tf.holds_files(folder)  # held: not stale
        assert bag.output_folder_problem(folder) == "exists and is not empty"
    finally:
        writer.send_signal(signal.SIGKILL)
        writer.wait()
    assert tf.stale_stages(folder) == [stage] and not tf.holds_files(folder)
    assert bag.output_folder_problem(folder) is None
    with tf.staged_folder(folder) as retry:
        (retry / "b_tensor.npy").write_bytes(b"whole")
    assert [p.name for p in folder.iterdir()] == ["b_tensor.npy"]


def test_an_export_whose_new_stage_another_export_cleans_up_writes_into_a_stage_of_its_own(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Another export's clean-up can come between the creation of a staging folder and its
    lock, when it is not yet held: it removed the folder, and this export's writes then went
    into nothing (FileNotFoundError). The clean-up takes the lock before it removes, and the
    export takes another staging folder when it finds its own removed."""
    import tempfile

    folder = tmp_path / "export"
    folder.mkdir()
    real_mkdtemp = tempfile.mkdtemp
    made: list[Path] = []

    def mkdtemp(*args: object, **kwargs: object) -> str:
        name = real_mkdtemp(*args, **kwargs)  # type: ignore[call-overload]
        made.append(Path(name))
        if len(made) == 1:  # the other export starts just after this folder was made
            with tf.staged_folder(folder) as other:
                (other / "k_tensor.npy").write_bytes(b"other")
        return name

    monkeypatch.setattr(tf.tempfile, "mkdtemp", mkdtemp)
    with tf.staged_folder(folder) as stage:
        (stage / "b_tensor.npy").write_bytes(b"whole")
    assert stage not in made[:2] and len(made) == 3  # its first was removed, the other's done
    assert sorted(p.name for p in folder.iterdir()) == ["b_tensor.npy", "k_tensor.npy"]


def test_remove_unheld_removes_only_what_no_process_holds(tmp_path: Path) -> None:
    """remove_unheld removes a file or folder that no process holds, and nothing else: not an
    entry of held_new while its descriptor is open, nor a link, nor a missing name."""
    import os
    import tempfile

    free_file, free_folder = tmp_path / "a.tmp", tmp_path / "b"
    free_file.write_bytes(b"x")
    (free_folder / "c").mkdir(parents=True)
    assert tf.remove_unheld(free_file) and tf.remove_unheld(free_folder)
    assert not free_file.exists() and not free_folder.exists()
    held, descriptor = tf.held_new(lambda: Path(tempfile.mkdtemp(dir=tmp_path)))
    try:
        assert not tf.remove_unheld(held) and held.is_dir() and tf.lock_held(held)
    finally:
        os.close(descriptor)
    assert tf.remove_unheld(held) and not held.exists()
    target = tmp_path / "target.tmp"
    target.write_bytes(b"y")
    (tmp_path / "link.tmp").symlink_to(target)
    assert not tf.remove_unheld(tmp_path / "link.tmp") and target.exists()
    assert not tf.remove_unheld(tmp_path / "missing.tmp")
