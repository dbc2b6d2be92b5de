"""``lit_planner.testing.read_until``, which the process tests use to wait for a child's line
without blocking the run when the line never comes (real child processes)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from lit_planner.testing import (
    ProcessIdentity,
    kill_identified,
    read_until,
    run_watched,
    start_time,
    still_running,
)

PRINTS_THEN_HANGS = (
    "import time\nprint('one', flush=True)\nprint('two', flush=True)\ntime.sleep(600)"
)


def _child(code: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)


def test_returns_the_lines_up_to_the_match_and_reads_no_further() -> None:
    process = _child("print('one')\nprint('two')\nprint('three')")
    try:
        assert process.stdout is not None
        assert read_until(process.stdout, "tw") == ["one\n", "two\n"]
        assert process.stdout.readline() == "three\n"
    finally:
        process.kill()
        process.wait()


def test_a_line_that_never_comes_fails_after_the_timeout() -> None:
    process = _child(PRINTS_THEN_HANGS)
    try:
        assert process.stdout is not None
        # (a read that blocked would see the stream end only when the child does, 600 s on)
        with pytest.raises(AssertionError, match=r"'three' not seen within 1 s; lines: one\ntwo"):
            read_until(process.stdout, "three", timeout=1.0)
    finally:
        process.kill()
        process.wait()


def test_a_stream_that_ends_first_fails_at_once() -> None:
    process = _child("print('one')")
    try:
        assert process.stdout is not None
        with pytest.raises(
            AssertionError, match="'two' not seen before the stream ended; lines: one"
        ):
            read_until(process.stdout, "two", timeout=600.0)
    finally:
        process.kill()
        process.wait()


GRANDCHILD = """
import os, subprocess, sys, time
child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"],
                         start_new_session=True)
print(child.pid, flush=True)
time.sleep(1.0)  # long enough for the watch to see its grandchild
"""


def test_run_watched_ends_what_the_command_left_behind() -> None:
    """A command that starts a process in a session of its own and exits: ``run_watched`` returns
    its output and code, names the process it started, and has ended it (by PID, start time
    checked); one that outlives its timeout raises TimeoutExpired with its output, its process
    ended as well."""

    def ended(identities: set[ProcessIdentity]) -> bool:
        deadline = time.monotonic() + 30.0  # SIGKILLed: gone once the kernel has ended it
        while still_running(identities) and time.monotonic() < deadline:
            time.sleep(0.05)
        return still_running(identities) == []

    result = run_watched([sys.executable, "-c", GRANDCHILD], timeout=60)
    try:
        assert result.returncode == 0, result.stderr
        left = int(result.stdout.split()[0])
        assert left in {pid for pid, _ in result.started}, (left, result.started)
        assert ended(result.started)
    finally:
        kill_identified(result.started)
    hung = [sys.executable, "-c", GRANDCHILD.replace("time.sleep(1.0)", "time.sleep(600)")]
    with pytest.raises(subprocess.TimeoutExpired) as raised:
        run_watched(hung, timeout=3)
    left = int(raised.value.output.split()[0])  # printed before the timeout
    deadline = time.monotonic() + 30.0
    while Path(f"/proc/{left}").exists() and start_time(left) is not None:
        assert time.monotonic() < deadline, f"{left} still runs"
        time.sleep(0.05)


_SLEEPING_TEST = """
import pathlib, time
import pytest

MARKS = pathlib.Path(__file__).parent

@pytest.fixture
def cleanup():
    yield
    (MARKS / "teardown").write_text("done")

def test_sleeps(cleanup):
    (MARKS / "started").write_text("yes")
    time.sleep(120)
"""


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP])
def test_lit_test_stopped_by_a_signal_lets_pytest_tear_down(tmp_path: Path, signum: int) -> None:
    """``kill PID`` of ``lit test`` (or its terminal closing) ended it at once, and pytest ran on,
    orphaned, with the nodes its tests had started; now pytest gets the Ctrl-C it handles, its
    fixtures tear down, and lit test exits 130 after it."""
    (tmp_path / "test_sleeping.py").write_text(_SLEEPING_TEST)
    root = Path(__file__).resolve().parents[2]
    process = subprocess.Popen(
        [sys.executable, "-m", "lit_planner.cli", "test", "--no-ctest", "--",
         str(tmp_path / "test_sleeping.py"), "-p", "no:cacheprovider"],
        cwd=root, env=dict(os.environ, LIT_SKIP_SETUP="1", ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"),
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while not (tmp_path / "started").exists():
            assert process.poll() is None and time.monotonic() < deadline, process.returncode
            time.sleep(0.1)
        process.send_signal(signum)
        out, _ = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 130, out
    assert (tmp_path / "teardown").read_text() == "done", out


def test_lit_test_sanitize_builds_the_tests_and_the_module_apart(tmp_path: Path) -> None:
    """``lit test --sanitize``: the GoogleTest binaries and the extension module with ASan and
    UBSan in a build tree of their own (the normal tree's ctest glob does not see it)."""
    from lit_planner import testing

    root = tmp_path / "checkout"
    configure, build = testing.sanitize_commands(root, 2, "/pybind11/cmake")
    assert configure[:5] == ["cmake", "-S", str(root / "lit_planner/core"), "-B",
                             str(root / testing.SANITIZE_DIR)]  # fmt: skip
    assert "-DLIT_BUILD_PYTHON=ON" in configure and "-DLIT_BUILD_TESTS=ON" in configure
    assert "-Dpybind11_DIR=/pybind11/cmake" in configure
    assert f"-DPython_EXECUTABLE={sys.executable}" in configure
    flags = next(arg for arg in configure if arg.startswith("-DCMAKE_CXX_FLAGS="))
    assert "-fsanitize=address,undefined" in flags and "-fno-sanitize-recover=undefined" in flags
    assert "-DCMAKE_MODULE_LINKER_FLAGS=-fsanitize=address,undefined" in configure
    assert build == ["cmake", "--build", str(root / testing.SANITIZE_DIR), "-j", "2"]
    configure, _ = testing.sanitize_commands(root, 2, None)  # --no-pytest: no module
    assert "-DLIT_BUILD_PYTHON=OFF" in configure and not any("pybind11" in a for a in configure)
    (root / testing.SANITIZE_DIR).mkdir(parents=True)
    (root / testing.SANITIZE_DIR / "CTestTestfile.cmake").write_text("")
    assert testing.find_ctest_dir(root) is None  # never taken for the normal build


def test_the_sanitized_python_tests_preload_the_runtime_and_read_its_reports(
    tmp_path: Path,
) -> None:
    """Python is not built with the sanitizers: their runtime is preloaded, libstdc++ after it
    (ASan's C++ exception interceptor failed a CHECK without it), the sanitized module comes first
    on PYTHONPATH, and reports go to files (pytest's capture of a test that a report ends is
    lost); a warning there is not a report."""
    import shutil

    from lit_planner import testing

    if shutil.which("g++") is None:
        pytest.skip("no g++ (the sanitizers' runtime comes with it)")
    build = tmp_path / "build"
    user = {"PYTHONPATH": "/ros/site", "LD_PRELOAD": "/my/lib.so", "UBSAN_OPTIONS": "mine=1"}
    env = testing.sanitized_python_environment(user, build, tmp_path)
    assert isinstance(env, dict), env
    preload = env["LD_PRELOAD"].split(":")
    assert "libasan.so" in preload[0] and "libstdc++.so" in preload[1]
    assert preload[2:] == ["/my/lib.so"]
    assert env["PYTHONPATH"].split(os.pathsep) == [str(build), "/ros/site"]
    assert env["ASAN_OPTIONS"].endswith(f":log_path={tmp_path / testing.SANITIZER_REPORT}")
    assert env["UBSAN_OPTIONS"] == "mine=1"  # the user's own options win
    # The runtime of the compiler the tree was configured with (a clang tree wants clang's).
    build.mkdir()
    cache = build / "CMakeCache.txt"
    cache.write_text("CMAKE_CXX_COMPILER:FILEPATH=/nonexistent/clang++\n")
    assert testing.sanitized_python_environment(user, build, tmp_path) == (
        "/nonexistent/clang++ not found (Debian package g++)"
    )
    cache.write_text(f"CMAKE_CXX_COMPILER:FILEPATH={shutil.which('g++')}\n")
    assert isinstance(testing.sanitized_python_environment(user, build, tmp_path), dict)
    report = testing.SANITIZER_REPORT
    (tmp_path / f"{report}.11").write_text("==11==AddressSanitizer: WARNING: unexpected format\n")
    assert testing.sanitizer_reports(tmp_path) == []
    error = "==12==ERROR: AddressSanitizer: heap-buffer-overflow on address 0x1\n"
    (tmp_path / f"{report}.12").write_text(error)
    (tmp_path / f"{report}.13").write_text("Worlds.cpp:3:5: runtime error: signed overflow\n")
    found = testing.sanitizer_reports(tmp_path)
    assert [path.name for path, _ in found] == [f"{report}.12", f"{report}.13"]
    assert found[0][1] == error
