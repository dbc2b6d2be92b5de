"""`lit call`'s standard output holds the answer alone, whatever native code writes."""

from __future__ import annotations

import subprocess
import sys

SCRIPT = """
import os, sys
from lit_planner.rosutil import native_output_to_stderr
native_output_to_stderr()
os.write(1, b"[RTPS_TRANSPORT_SHM Error] Failed init_port fastrtps_port7003\\n")  # as Fast DDS does
print('{"code": "ok"}')
"""


def test_native_writes_to_standard_output_go_to_standard_error() -> None:
    """A Fast DDS log line on descriptor 1 once broke `lit call --payload-only | json` (seen in a
    CI run with stale shared-memory locks); it must land on standard error instead."""
    result = subprocess.run(
        [sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=60, check=True
    )
    assert result.stdout == '{"code": "ok"}\n'
    assert "Failed init_port fastrtps_port7003" in result.stderr
