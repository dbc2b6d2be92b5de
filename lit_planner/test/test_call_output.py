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


def test_an_answer_that_cannot_be_written_is_a_stdout_error_after_the_redirect() -> None:
    """The answers' stream that `lit call` and `lit demo` print to after the redirect is guarded
    as lit's own standard output is: a full disk is one line from `lit`, not a traceback."""
    script = (
        "import os, sys\n"
        "from lit_planner.guarded_stdout import StdoutError\n"
        "from lit_planner.rosutil import native_output_to_stderr\n"
        "native_output_to_stderr()\n"
        "try:\n"
        "    print('{}', flush=True)\n"
        "except StdoutError as error:\n"
        "    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # as lit does\n"
        "    raise SystemExit(f'StdoutError: {error}')\n"
    )
    with open("/dev/full", "w") as full:  # a device, written as a shell would
        result = subprocess.run(
            [sys.executable, "-c", script], stdout=full, stderr=subprocess.PIPE, text=True,
            timeout=60, check=False,
        )  # fmt: skip
    assert result.stderr.strip() == "StdoutError: [Errno 28] No space left on device", result
