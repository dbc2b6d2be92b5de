"""Fixtures shared by the system tests."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from ros_helpers import RosSystem


@pytest.fixture
def ros(tmp_path: Path) -> Iterator[RosSystem]:
    """The processes of one test, in a domain of their own, stopped by PID at the end."""
    system = RosSystem(tmp_path)
    try:
        yield system
    finally:
        system.close()
