"""``lit tensors constant``: constant lookup tensors the tensor policy plays as they are."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from cli_helpers import lit

from lit_planner import tensor_files as tf


def test_constant_tensors_are_what_the_planner_decides(tmp_path: Path) -> None:
    out = tmp_path / "constant"
    process = lit("tensors", "constant", "--b", "150", "--psi-k", "6.5", "--out", str(out))
    assert process.returncode == 0, process.stderr
    for name, output, value in (("b_tensor", "B", 150.0), ("k_tensor", "psi_K", 6.5)):
        data, sidecar = tf.read_tensor(out / f"{name}.npy")  # validates file, sidecar and hash
        assert sidecar.output == output and (data == value).all()
        assert sidecar.provenance["constant"] == value
        assert sidecar.provenance["command"].startswith("lit tensors constant --b 150")
        assert "decision_interval" not in sidecar.provenance  # the planner's default applies
    planned = lit(
        "plan", "--scenario", "np4", "--policy", "tensor", "--tensors", str(out),
        "--iterations", "3000", "--json",
    )  # fmt: skip
    assert planned.returncode == 0, planned.stderr
    result = json.loads(planned.stdout)
    kinds = {"B": [], "psi_K": []}  # type: dict[str, list[float]]
    for decision in result["decisions"]:
        kinds[decision["kind"]].append(decision["value"])
    assert kinds["B"] and kinds["psi_K"]  # both decided: solutions were found, and expansions
    assert set(kinds["B"]) == {150.0} and set(kinds["psi_K"]) == {6.5}


def test_one_tensor_alone_and_the_fallback_of_the_other(tmp_path: Path) -> None:
    process = lit("tensors", "constant", "--psi-k", "3", "--out", str(tmp_path))
    assert process.returncode == 0, process.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["k_tensor.json", "k_tensor.npy"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ([], "give --b and/or --psi-k: the value(s) to write"),
        (["--b", "201"], "B = 201 is outside its range 20..200"),
        (["--b", "20.5"], "B = 20.5 is not a whole number"),  # was argparse's usage, 3 lines
        (["--b", "nan"], "B = nan is outside its range 20..200"),
        (["--b", "100", "--psi-k", "2.5"], "psi_K = 2.5 is outside its range 3..15"),
        (["--psi-k", "nan"], "psi_K = nan is outside its range 3..15"),
        (["--b", "100"], "b_tensor.npy: already there; choose another --out"),
        # Another parameter's tensor would be played with the new one: refused as well.
        (["--psi-k", "6"], "b_tensor.npy: already there; choose another --out"),
        (["--b", "100", "--decision-interval", "10"], "applies to psi_K: give --psi-k too"),
        (["--psi-k", "6", "--decision-interval", "0"], "got 0"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(
    tmp_path: Path, args: list[str], message: str
) -> None:
    (tmp_path / "b_tensor.npy").write_bytes(b"kept")  # somebody's file: must survive
    process = lit("tensors", "constant", *args, "--out", str(tmp_path))
    assert process.returncode == 2
    assert process.stdout == ""
    (line,) = process.stderr.strip().splitlines()
    assert line.startswith("lit tensors: ") and line.endswith(message)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b_tensor.npy"]
    assert (tmp_path / "b_tensor.npy").read_bytes() == b"kept"


@pytest.mark.parametrize(
    "args",
    [
        ["tensors", "constant", "--b", "100", "--out"],
        ["bench", "--quick", "--no-bag", "--out"],
        ["train", "--episodes", "1", "--out"],
        ["replay", "info"],
        ["plan", "--scenario", "np4", "--policy", "tensor", "--tensors"],
    ],
)
def test_an_empty_path_is_refused_not_taken_for_here(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, args: list[str]
) -> None:
    """``--out ""`` (an unset shell variable) used to write into the current folder."""
    monkeypatch.chdir(tmp_path)
    process = lit(*args, "")
    assert process.returncode == 2
    assert "empty path (an unset shell variable?)" in process.stderr
    assert "Traceback" not in process.stderr
    assert list(tmp_path.iterdir()) == []


def test_a_file_as_the_folder_is_refused(tmp_path: Path) -> None:
    target = tmp_path / "file"
    target.write_text("x")
    process = lit("tensors", "constant", "--b", "100", "--out", str(target))
    assert process.returncode == 2 and "a file, not a folder" in process.stderr
    assert target.read_text() == "x"


def test_info_shows_the_shipped_tensors() -> None:
    shipped = str(Path(__file__).resolve().parents[2] / "tensors")
    process = lit("tensors", "info", shipped, "--json")
    assert process.returncode == 0, process.stderr
    document = json.loads(process.stdout)
    b, k = document["tensors"]["b_tensor.npy"], document["tensors"]["k_tensor.npy"]
    assert b["output"] == "B" and k["output"] == "psi_K"
    assert k["decision_interval"] == k["provenance"]["decision_interval"]
    for entry in (b, k):
        low, high = entry["range"]
        spread = list(entry["percentiles"].values())
        assert low <= spread[0] <= spread[-1] <= high and spread == sorted(spread)
    readable = lit("tensors", "info", shipped)
    assert readable.returncode == 0 and "checked" in readable.stdout
    assert f"psi_K decided every {k['decision_interval']} expansions" in readable.stdout
    for entry in (b, k):  # the shipped tensors were trained
        assert entry["training"]["updates"] > 0
        assert f"{entry['training']['updates']} gradient updates from" in readable.stdout
    assert "UNTRAINED" not in readable.stdout


def test_info_marks_an_untrained_export(tmp_path: Path) -> None:
    """An export of an actor no gradient step has changed (a psi_K agent whose phase has not
    begun, a bag without its decisions) is marked, not shown like a trained tensor."""
    from lit_learner.config import LearnerConfig
    from lit_learner.core import LearnerCore

    LearnerCore(LearnerConfig(seed=0)).export_tensors(tmp_path, {"note": "untrained"})
    readable = lit("tensors", "info", str(tmp_path))
    assert readable.returncode == 0, readable.stderr
    assert readable.stdout.count("0 gradient updates from 0 transitions; UNTRAINED") == 2


def test_info_shows_the_resume_that_wrote_an_export(tmp_path: Path) -> None:
    """The run's first command alone was shown, without --export, for an export a resume wrote."""
    from lit_learner.config import LearnerConfig
    from lit_learner.core import LearnerCore

    provenance = {
        "command": "lit train --episodes 6",
        "resumed_with": ["lit train --resume R --episodes 8", "lit train --resume R --export X"],
    }
    LearnerCore(LearnerConfig(seed=0)).export_tensors(tmp_path, provenance)
    readable = lit("tensors", "info", str(tmp_path))
    assert readable.returncode == 0, readable.stderr
    assert readable.stdout.count("    command     lit train --episodes 6\n") == 2
    assert (
        readable.stdout.count(
            "    resumed     lit train --resume R --export X (the last of 2 resumes)\n"
        )
        == 2
    ), readable.stdout


def test_info_prints_the_provenance_escaped(tmp_path: Path) -> None:
    """A sidecar's provenance with a lone surrogate was a UnicodeEncodeError traceback (the
    planner plays the same folder), and control characters went to the terminal raw."""
    provenance = {"command": "\ud800 lit train \x1b[31m\u202e"}
    from lit_learner.config import LearnerConfig
    from lit_learner.core import LearnerCore

    LearnerCore(LearnerConfig(seed=0)).export_tensors(tmp_path, provenance)
    readable = lit("tensors", "info", str(tmp_path))
    assert readable.returncode == 0 and "Traceback" not in readable.stderr, readable.stderr
    assert readable.stdout.count("    command     \\ud800 lit train \\x1b[31m\\u202e\n") == 2


def test_info_names_a_defective_tensor_and_still_shows_the_other(tmp_path: Path) -> None:
    assert (
        lit("tensors", "constant", "--b", "80", "--psi-k", "4", "--out", str(tmp_path)).returncode
        == 0
    )
    data = bytearray((tmp_path / "k_tensor.npy").read_bytes())
    data[-1] ^= 0xFF  # one flipped byte: the hash no longer matches
    (tmp_path / "k_tensor.npy").write_bytes(bytes(data))
    process = lit("tensors", "info", str(tmp_path))
    assert process.returncode == 2
    assert (
        "k_tensor.npy: DEFECTIVE" in process.stdout
        and "b_tensor.npy: B in 20..200" in process.stdout
    )
    (line,) = process.stderr.strip().splitlines()
    assert "k_tensor.npy: data SHA-256" in line
    assert "interval    not named" not in process.stdout


def test_info_refuses_tensors_that_the_planner_cannot_use_together(tmp_path: Path) -> None:
    """Each sidecar valid, but naming different lookup modes: `lit plan` refused the folder while
    `lit tensors info` passed it."""
    assert (
        lit("tensors", "constant", "--b", "80", "--psi-k", "4", "--out", str(tmp_path)).returncode
        == 0
    )
    sidecar = tmp_path / "k_tensor.json"
    document = json.loads(sidecar.read_text())
    document["interpolation"] = "nearest" if document["interpolation"] != "nearest" else "trilinear"
    sidecar.write_text(json.dumps(document))
    plan = lit("plan", "--scenario", "np4", "--policy", "tensor", "--tensors", str(tmp_path))
    info = lit("tensors", "info", str(tmp_path))
    for process in (plan, info):
        assert process.returncode == 2, process.stdout + process.stderr
        (line,) = process.stderr.strip().splitlines()
        assert "the sidecars name different lookup modes" in line, line
    assert "b_tensor.npy: B in 20..200" in info.stdout  # each tensor is still shown
    assert (
        "different lookup modes"
        in json.loads(lit("tensors", "info", str(tmp_path), "--json").stdout)["error"]
    )


@pytest.mark.parametrize("make", ["empty", "file"])
def test_info_without_tensors_is_one_line(tmp_path: Path, make: str) -> None:
    target = tmp_path / "t"
    if make == "empty":
        target.mkdir()
    else:
        target.write_text("x")
    process = lit("tensors", "info", str(target))
    assert process.returncode == 2 and process.stdout == ""
    (line,) = process.stderr.strip().splitlines()
    assert line.startswith(f"lit tensors: {target}: ")


def test_a_decision_interval_is_what_the_tensor_policy_applies(tmp_path: Path) -> None:
    from lit_planner import planning

    process = lit(
        "tensors", "constant", "--psi-k", "5", "--decision-interval", "7", "--out", str(tmp_path)
    )
    assert process.returncode == 0, process.stderr
    assert planning.trained_decision_interval(tmp_path / "k_tensor.npy") == 7
    policy = planning.make_policy("tensor", tmp_path)
    assert planning.policy_params(policy) == {"decision_interval": "7"}
    info = json.loads(lit("tensors", "info", str(tmp_path), "--json").stdout)
    assert info["tensors"]["k_tensor.npy"]["decision_interval"] == 7


def test_a_failed_write_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from lit_planner import tensors_cli

    real = tf.write_tensor
    calls = []

    def second_fails(*args: object, **kwargs: object) -> object:
        calls.append(args)
        if len(calls) == 2:
            raise OSError(28, "No space left on device")
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(tf, "write_tensor", second_fails)
    with pytest.raises(tensors_cli.TensorFileError, match="tensors not written: .*No space left"):
        tensors_cli.write_constant(tmp_path, 100, 6.0)
    assert list(tmp_path.iterdir()) == []
    # A parent that is a file: one line, exit 2.
    (tmp_path / "file").write_text("x")
    process = lit("tensors", "constant", "--b", "100", "--out", str(tmp_path / "file" / "sub"))
    assert process.returncode == 2 and "tensors not written" in process.stderr
    assert len(process.stderr.strip().splitlines()) == 1


def test_help_describes_both_actions() -> None:
    """The description covers ``info`` too, not only the constant tensors."""
    process = lit("tensors", "--help")
    assert process.returncode == 0, process.stderr
    usage, description = process.stdout.split("\n\n")[:2]
    assert usage.startswith("usage: lit tensors")
    description = " ".join(description.split())
    assert description.startswith("Look into lookup tensors and make them without training")
    assert "info checks a folder's tensors" in description
    assert "constant writes tensors" in description
