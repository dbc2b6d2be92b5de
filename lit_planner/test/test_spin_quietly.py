"""``rosutil.spin_quietly``: which errors of a spin it lets through, hides or reports (and
``rosutil.flush_publishers``'s one deadline for all publishers).

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


def test_flush_publishers_waits_at_most_its_timeout_for_all_publishers_together() -> None:
    """The timeout applied to each publisher in turn: the planner node's five publishers could
    wait 25 s at shutdown, more than ``lit up`` gives a node to stop."""
    import time

    from lit_planner.rosutil import flush_publishers

    class Publisher:
        def __init__(self, takes: float) -> None:
            self.takes, self.given = takes, None

        def wait_for_all_acked(self, timeout) -> bool:
            self.given = timeout.nanoseconds / 1e9
            time.sleep(min(self.takes, self.given))
            return self.takes <= self.given

    slow, late = Publisher(0.3), Publisher(0.0)
    assert flush_publishers([slow, late], timeout=1.0)
    assert slow.given == pytest.approx(1.0, abs=0.01)
    assert late.given <= 0.7  # what the first one left of the second
    stuck, never = Publisher(5.0), Publisher(0.0)
    assert not flush_publishers([stuck, never], timeout=0.2)
    assert never.given is None  # not asked once the time is up
