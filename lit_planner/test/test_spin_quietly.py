"""``rosutil.spin_quietly``: which errors of a spin it lets through, hides or reports.

The executor here is a stand-in whose ``spin`` raises; the ROS tests (tests/) run the real
executors through the same function.
"""

from __future__ import annotations

import pytest
import rclpy
from lit_planner.rosutil import spin_quietly
from rclpy._rclpy_pybind11 import InvalidHandle, RCLError


class RaisingExecutor:
    def __init__(self, exc: BaseException) -> None:
        self.exc = exc

    def spin(self) -> None:
        raise self.exc


def test_an_error_outside_a_shutdown_propagates(monkeypatch):
    monkeypatch.setattr(rclpy, "ok", lambda *a, **k: True)
    with pytest.raises(ValueError, match="boom"):
        spin_quietly(RaisingExecutor(ValueError("boom")), lambda: False)


@pytest.mark.parametrize("exc", [InvalidHandle("gone"), RCLError("context is not valid")])
def test_the_known_shutdown_races_are_silent(monkeypatch, capsys, exc):
    monkeypatch.setattr(rclpy, "ok", lambda *a, **k: True)
    spin_quietly(RaisingExecutor(exc), lambda: True)
    assert capsys.readouterr().err == ""


def test_other_errors_while_stopping_are_reported_not_raised(monkeypatch, capsys):
    monkeypatch.setattr(rclpy, "ok", lambda *a, **k: True)
    spin_quietly(RaisingExecutor(ValueError("a callback failed")), lambda: True)
    err = capsys.readouterr().err
    assert "while stopping" in err
    assert "ValueError: a callback failed" in err


def test_an_error_after_the_context_ended_is_reported_not_raised(monkeypatch, capsys):
    monkeypatch.setattr(rclpy, "ok", lambda *a, **k: False)
    spin_quietly(RaisingExecutor(KeyError("late")), lambda: False)
    assert "KeyError" in capsys.readouterr().err


def test_a_ctrl_c_in_the_spin_ends_it_quietly(monkeypatch, capsys):
    monkeypatch.setattr(rclpy, "ok", lambda *a, **k: True)
    spin_quietly(RaisingExecutor(KeyboardInterrupt()), lambda: False)
    assert capsys.readouterr().err == ""
