"""``lit train`` stopped by Ctrl-C or SIGTERM as a user stops it: a real process, signalled at
whatever point it has reached. The first signal lets the running episode, its end and any
checkpoint finish, then the run stops with a final checkpoint that resumes. (A KeyboardInterrupt
raised where Python happened to be used to abort a query inside the core's decision callback,
losing the run, or leave the learner's episode open, so the final checkpoint could not be
resumed.) A second signal stops at once."""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from lit_planner.testing import read_until

from lit_learner import train


@contextmanager
def _train(*args: str) -> Iterator[subprocess.Popen[str]]:
    """``lit train --no-progress ARGS`` running; killed at the end if the test left it running."""
    process = subprocess.Popen(
        [sys.executable, "-m", "lit_planner.cli", "train", "--no-progress", *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"),
    )  # fmt: skip
    try:
        yield process
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


def _arguments(*args: str) -> argparse.Namespace:
    """``lit train --no-progress ARGS`` parsed, for :func:`lit_learner.train.train`."""
    parser = argparse.ArgumentParser()
    train.add_arguments(parser)
    return parser.parse_args(["--no-progress", *args])


def _rows(run: Path) -> int:
    """Episodes in the run's metrics file so far."""
    try:
        return max(0, len((run / train.METRICS_FILE).read_text().splitlines()) - 1)
    except FileNotFoundError:
        return 0


def _wait_for_episodes(process: subprocess.Popen[str], run: Path, count: int) -> None:
    deadline = time.monotonic() + 300.0
    while _rows(run) < count:
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, f"fewer than {count} episodes in 300 s"
        time.sleep(0.02)


@pytest.mark.parametrize(
    ("sig", "after"), [(signal.SIGINT, 1), (signal.SIGTERM, 3), (signal.SIGHUP, 2)]
)  # SIGHUP (the terminal closed) ended the run at once, without its final checkpoint
def test_a_signal_stops_after_the_episode_with_a_checkpoint_that_resumes(
    tmp_path: Path, sig: signal.Signals, after: int
) -> None:
    from lit_learner.core import LearnerCore

    run = tmp_path / "run"
    # Joint schedule: both agents decide, psi_K at every expansion, so the signal most likely
    # lands inside a decision the C++ core called back.
    with _train("--scenarios", "np4", "--episodes", "100000", "--schedule", "joint",
                "--no-bag", "--checkpoint-every", "0", "--out", str(run)) as process:  # fmt: skip
        _wait_for_episodes(process, run, after)
        process.send_signal(sig)
        out, err = process.communicate(timeout=300)
    assert process.returncode == 130, out + err
    assert "stopping after this episode" in err and "Traceback" not in err, err
    assert "(interrupted: --resume the final checkpoint" in out, out
    final = run / train.CHECKPOINT_DIR / "final.ckpt"
    state = train.DriverState.load(train.state_path(final))
    assert state.episode == _rows(run) >= after
    assert LearnerCore.load_checkpoint(final).open_episodes() == set()

    with _train(
        "--resume", str(final), "--episodes", str(state.episode + 2), "--no-bag"
    ) as resumed:
        out, err = resumed.communicate(timeout=300)
    assert resumed.returncode == 0, out + err
    assert _rows(run) == state.episode + 2


def test_a_second_signal_stops_at_once(tmp_path: Path) -> None:
    run = tmp_path / "run"
    # Episodes of 12 s (budget 0.12 s x 100): the second signal comes while one runs. Joint
    # schedule: psi_K decided at every expansion, so the C++ core calls back into Python all the
    # time and each signal's handler runs at once (in the B phase's rare callbacks the first
    # handler could wait for the episode's end, and the second then came after it: a CI failure).
    with _train("--scenarios", "np4", "--episodes", "100000", "--budget-scale", "100",
                "--schedule", "joint", "--no-bag", "--out", str(run)) as process:  # fmt: skip
        _wait_for_episodes(process, run, 1)
        # Into the second episode: the first row is written before the next episode starts, and
        # a signal in between stopped the run before it (on a busy machine: a CI failure); the
        # second signal then came while the final outputs were written, and did not stop it.
        time.sleep(2.0)
        process.send_signal(signal.SIGINT)
        assert process.stderr is not None
        # the first one taken (two at once may arrive as one)
        seen = read_until(process.stderr, "stopping after this episode")
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=300)
        err = "".join(seen) + err
    assert process.returncode == 130, out + err
    assert "stopped at once" in err and "Traceback" not in err, err
    assert not (run / train.CHECKPOINT_DIR / "final.ckpt").exists()


def test_a_second_signal_while_the_outputs_are_written_is_ignored(tmp_path: Path) -> None:
    """Once the episodes are over, the final checkpoint, curves, provenance and export take
    seconds (the two 101^3 tensors); a second Ctrl-C then must not leave them half written."""
    from lit_planner.tensor_files import read_tensor
    from test_train_driver import tiny_config

    # Both agents update from their first transition (lit train exports only agents that made
    # a gradient update; the defaults wait for 500 and 10 000 transitions).
    config = tiny_config()
    run, export = tmp_path / "run", tmp_path / "tensors"
    train.train(
        _arguments("--scenarios", "np4", "--episodes", "1", "--schedule", "joint", "--no-bag",
                   "--out", str(run)),
        train.TrainingHooks(learner_config=config),
    )  # fmt: skip
    start = run / train.CHECKPOINT_DIR / "final.ckpt"
    with _train("--resume", str(start), "--episodes", "100000", "--checkpoint-every", "0",
                "--export", str(export)) as process:  # fmt: skip
        _wait_for_episodes(process, run, 2)
        # The driver state is written right after the final checkpoint, before the export.
        driver = train.state_path(start)
        written = driver.stat().st_mtime_ns
        process.send_signal(signal.SIGINT)
        deadline = time.monotonic() + 300.0
        while driver.stat().st_mtime_ns == written:
            assert process.poll() is None, process.communicate()
            assert time.monotonic() < deadline, "no final checkpoint in 300 s"
            time.sleep(0.01)
        process.send_signal(signal.SIGINT)
        process.send_signal(signal.SIGTERM)
        out, err = process.communicate(timeout=300)
    assert process.returncode == 130, out + err
    assert "writing the final checkpoint and outputs" in err, err
    assert "stopped at once" not in err and "Traceback" not in err, err
    for name in ("b_tensor.npy", "k_tensor.npy"):
        values, sidecar = read_tensor(export / name)  # checks the data against its SHA-256
        assert values.shape == (101, 101, 101), name
        assert sidecar.training["updates"] > 0, name
    assert (export / "provenance.json").exists() and (export / "training_curves.png").exists()
