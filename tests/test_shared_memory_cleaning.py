"""The test session's clean-up of Fast DDS's shared memory (``tests/conftest.py``)."""

from __future__ import annotations

import fcntl
import re
import secrets
from pathlib import Path

import pytest
from conftest import clean_fast_dds_shared_memory

SHM = Path("/dev/shm")


@pytest.mark.skipif(not SHM.is_dir(), reason="no /dev/shm")
def test_only_the_segments_of_gone_processes_are_removed() -> None:
    """Two segments as Fast DDS lays them out (the segment and its ``_el`` lock file): the one
    whose lock is held, as a running process holds it, stays; the other goes."""
    live, zombie = (SHM / f"fastrtps_{secrets.token_hex(8)}" for _ in range(2))
    files = [live, Path(f"{live}_el"), zombie, Path(f"{zombie}_el")]
    for path in files:
        path.write_bytes(b"")
    try:
        with open(f"{live}_el", "ab") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            report = clean_fast_dds_shared_memory()
            cleaned = re.search(r"(\d+) zombie segments cleaned", report)
            assert cleaned is not None and int(cleaned.group(1)) >= 1, report
            assert live.exists() and Path(f"{live}_el").exists()
            assert not zombie.exists() and not Path(f"{zombie}_el").exists()
    finally:
        for path in files:
            path.unlink(missing_ok=True)
