"""``lit test``: every test of the checkout, C++ through ctest and Python through pytest.

The C++ GoogleTest binaries live in the core's persistent build tree
(``lit_planner/core/build/<wheel tag>/``, registered with ctest); the Python tests live in
``tests/`` and in each package's ``test/`` directory. Both runners write JUnit XML into a temporary
directory, and the counts come from there. Every child process runs with DDS discovery confined to
this host and with a ROS domain reserved for this run, so concurrent runs do not hear each other.

The last line printed is always::

    lit test: <P> passed, <F> failed (ctest <p1>/<n1>, pytest <p2>/<n2>)

and the exit status is non-zero when anything failed, a runner broke, or no test ran at all.
"""

from __future__ import annotations

import argparse
import itertools
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any
from xml.etree import ElementTree

from lit_planner import signals
from lit_planner.up import DomainBusy, DomainClaim, claim_domain

PYTHON_TEST_DIRS = ("tests", "lit_planner/test", "lit_learner/test", "lit_msgs_json/test")
"""Python test directories, relative to the checkout root; missing ones are skipped."""
PYTEST_HANG_DUMP_S = 600
"""Seconds after which a still-running pytest test has its threads' stacks printed."""
CTEST_GLOB = "lit_planner/core/build/*/CTestTestfile.cmake"
"""Where the core's scikit-build-core build tree registers its GoogleTest binaries."""
SANITIZE_DIR = "lit_planner/core/build-sanitize"
"""``lit test --sanitize``'s build tree of the GoogleTest binaries and the extension module."""
SANITIZERS = "-fsanitize=address,undefined"
"""AddressSanitizer (with LeakSanitizer) and UndefinedBehaviorSanitizer."""
SANITIZE_ENV = {
    "ASAN_OPTIONS": "detect_leaks=1:abort_on_error=0",
    # Any undefined behaviour fails its test (the build makes it fatal too).
    "UBSAN_OPTIONS": "print_stacktrace=1:halt_on_error=1",
}
SANITIZE_PYTHON_TESTS = (
    "lit_planner/test/test_planning_api.py",
    "lit_planner/test/test_plan_cli.py",
    "lit_planner/test/test_crosscheck.py",
    "lit_planner/test/test_ompl2_checker.py",
    "lit_planner/test/test_tensor_files.py",
    "lit_planner/test/test_tensors_cli.py",
    "lit_learner/test/test_learner_export.py",
    "lit_learner/test/test_train_driver.py",
)
"""The Python tests that ``lit test --sanitize`` runs against the sanitized extension module: those
that drive ``lit_core`` (planning, policies, tensors, training through the external policy)
without ROS nodes, whose processes would run sanitized as well."""
SANITIZE_PYTHON_ENV = {
    # Python's own allocations are left at exit on purpose: leaks are checked by the C++ tests.
    "ASAN_OPTIONS": "detect_leaks=0:abort_on_error=0",
    "UBSAN_OPTIONS": "print_stacktrace=1:halt_on_error=1",
}
SANITIZER_REPORT = "sanitizer-report"
"""Stem of the files the sanitizers write their reports to in the Python tests (``log_path``):
pytest's capture of a test's output is lost when a report ends the process."""
ROS_DOMAIN_IDS = range(1, 101)
"""Domains a test run may reserve (ROS allows 0-232; 0 is everyone's default, so avoid it)."""


@dataclass
class RunnerResult:
    """What one test runner reported."""

    name: str
    passed: int = 0
    failed: int = 0
    skipped: int = 0
    error: str | None = None
    """Set when the runner itself broke (no report, crash, usage error): the run fails."""

    @property
    def ran(self) -> int:
        return self.passed + self.failed


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``lit test``."""
    parser.add_argument(
        "-k", dest="keyword", metavar="EXPR", help="only run pytest tests matching EXPR (pytest -k)"
    )
    parser.add_argument(
        "-R",
        "--ctest-regex",
        metavar="REGEX",
        help="only run ctest tests whose name matches REGEX (ctest -R)",
    )
    parser.add_argument(
        "--sanitize",
        action="store_true",
        help=f"build the C++ tests and the extension module with AddressSanitizer and "
        f"UndefinedBehaviorSanitizer in {SANITIZE_DIR}/ and run the C++ tests and the Python "
        "tests that drive the module without ROS (-R, -k, --no-ctest, --no-pytest and test "
        "paths after -- apply)",
    )
    parser.add_argument("--no-ctest", action="store_true", help="skip the C++ tests")
    parser.add_argument("--no-pytest", action="store_true", help="skip the Python tests")
    parser.add_argument(
        "pytest_args",
        nargs="*",
        metavar="PYTEST_ARG",
        help='after "--": passed to pytest as is; test paths given here replace '
        "the default test directories",
    )


def repo_root() -> Path:
    """The checkout: ``$LIT_ROOT`` (set by ``./lit``), else found above this (editable) file."""
    if os.environ.get("LIT_ROOT"):
        return Path(os.environ["LIT_ROOT"]).resolve()
    for parent in Path(__file__).resolve().parents:
        if (parent / "lit_planner" / "core" / "CMakeLists.txt").is_file():
            return parent
    raise SystemExit("lit test: cannot locate the LIT* checkout; set LIT_ROOT")


def reserve_ros_domain(
    domains: Sequence[int] = ROS_DOMAIN_IDS, start: int | None = None
) -> tuple[int, DomainClaim | None]:
    """Pick a free ROS_DOMAIN_ID from ``domains``, searching from index ``start`` (default:
    derived from the PID).

    The domain is claimed with the launchers' lock (:func:`lit_planner.up.claim_domain`), held
    until the returned claim is closed: concurrent test runs and ``lit up``, ``lit demo`` or
    ``lit system-bench`` of this host keep out of each other's domain, whichever came first.
    Returns the domain and its claim, or the first candidate and None when every one is taken
    (share one rather than refuse to test).
    """
    first = (os.getpid() if start is None else start) % len(domains)
    for offset in range(len(domains)):
        domain = domains[(first + offset) % len(domains)]
        try:
            claim = claim_domain(domain, "lit test", warn=False)
        except DomainBusy:
            continue
        if claim.held:
            return domain, claim
    return domains[first], None


def descendants(pid: int) -> set[int]:
    """PIDs of ``pid``'s children, grandchildren, ... now (from /proc)."""
    parents: dict[int, int] = {}
    for entry in os.listdir("/proc"):
        fields = _stat_fields(int(entry)) if entry.isdigit() else None
        if fields is not None:
            parents[int(entry)] = int(fields[1])
    found, frontier = set(), {pid}
    while frontier:
        frontier = {child for child, parent in parents.items() if parent in frontier} - found
        found |= frontier
    return found


ProcessIdentity = tuple[int, int | None]
"""A process as (PID, start time): a PID reused by another process no longer matches."""


def identify(pids: Iterable[int]) -> set[ProcessIdentity]:
    """The identities of ``pids`` now (a process already gone gets start time None)."""
    return {(pid, start_time(pid)) for pid in pids}


def still_running(identities: Iterable[ProcessIdentity]) -> list[int]:
    """PIDs of the identified processes that still run (the same process: its start time is
    unchanged; a zombie has ended)."""
    return sorted(pid for pid, start in identities if start and start_time(pid) == start)


def kill_identified(identities: Iterable[ProcessIdentity]) -> None:
    """SIGKILL the identified processes that still run, and no process that took a PID over."""
    for pid in still_running(identities):
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:  # it ended meanwhile
            pass


class DescendantWatch:
    """Every process ``pid`` started, directly or not, while it ran (polled from /proc on a
    thread): the nodes a launcher starts in sessions of their own, which ``os.killpg`` of the
    launcher's group does not reach. :meth:`alive` names those still running once it ended;
    :meth:`kill` ends them by PID."""

    def __init__(self, pid: int, interval: float = 0.1) -> None:
        self.pid = pid
        self.seen: set[ProcessIdentity] = set()
        """(PID, start time) of every descendant seen."""
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._poll, args=(interval,), daemon=True)
        self._thread.start()

    def _poll(self, interval: float) -> None:
        while not self._stop.is_set():
            self.seen |= identify(descendants(self.pid))
            self._stop.wait(interval)

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()

    def alive(self) -> list[int]:
        """Processes seen that still run (the same process: its start time is unchanged)."""
        self.stop()
        return still_running(self.seen)

    def kill(self) -> None:
        self.stop()
        kill_identified(self.seen)


class Watched(subprocess.CompletedProcess):  # type: ignore[type-arg]
    """:func:`run_watched`'s result: a ``CompletedProcess`` that also names every process the
    command started (``started``: each descendant seen while it ran, ended by then)."""

    started: set[ProcessIdentity]


def run_watched(args: Sequence[str], *, timeout: float, **options: object) -> Watched:
    """``subprocess.run(args, capture_output=True, text=True, timeout=timeout, **options)`` that
    also ends whatever the command started, even in sessions of their own (ROS nodes that a
    launcher should not have started, or left behind): every descendant seen while it ran is
    SIGKILLed by PID afterwards, as is the command if it outlived ``timeout`` (then
    TimeoutExpired, as from ``subprocess.run``, with the output so far). The result names them
    (``started``), so a test that expects nothing started can say so. The output goes through
    files, so a process left behind that holds them open does not keep this waiting."""
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:

        def texts() -> list[str]:
            read = []
            for stream in (out, err):
                stream.seek(0)
                read.append(stream.read().decode("utf-8", errors="replace"))
            return read

        process = subprocess.Popen(
            args,
            stdout=out,
            stderr=err,
            start_new_session=True,
            **options,  # type: ignore[call-overload]
        )
        watch = DescendantWatch(process.pid)
        try:
            code = process.wait(timeout=timeout)
        except subprocess.TimeoutExpired as expired:
            expired.output, expired.stderr = texts()
            raise
        finally:
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()
            watch.kill()
        result = Watched(args, code, *texts())
        result.started = watch.seen
        return result


def longest_chord_inside_boxes(scenario: Any, path: Any) -> float:
    """The longest piece of any segment of ``path`` inside any obstacle box of ``scenario`` (a
    :class:`lit_planner.scenarios.Scenario`), exactly (slab method): 0 for a path that touches
    boxes at most, corners and edges included."""
    import numpy as np

    path = np.asarray(path, dtype=np.float64)
    lower, upper = scenario.boxes[:, 0], scenario.boxes[:, 1]  # (m, dim)
    longest = 0.0
    for a, b in itertools.pairwise(path):
        d = b - a
        with np.errstate(divide="ignore", invalid="ignore"):
            t1, t2 = (lower - a) / d, (upper - a) / d  # (m, dim); inf/nan where d == 0
        flat = d == 0
        inside = np.all(~flat | ((lower <= a) & (a <= upper)), axis=1)  # parallel axes
        enter = np.where(flat, -np.inf, np.minimum(t1, t2)).max(axis=1).clip(0.0, 1.0)
        leave = np.where(flat, np.inf, np.maximum(t1, t2)).min(axis=1).clip(0.0, 1.0)
        chord = np.where(inside, np.maximum(leave - enter, 0.0), 0.0) * np.linalg.norm(d)
        longest = max(longest, float(chord.max(initial=0.0)))
    return longest


def read_until(stream: IO[str], text: str, timeout: float = 120.0) -> list[str]:
    """Lines of a child's ``stream`` up to and including the first one that holds ``text``.

    The lines are read on a thread, so that a child that never prints ``text`` (or hangs before
    it) fails the test after ``timeout`` seconds instead of blocking the run: AssertionError with
    the lines seen. Nothing past the matching line is read here. After a timeout the thread may
    still be blocked in its read until the caller ends the child (which closes the pipe).
    """
    lines: list[str] = []
    found = threading.Event()

    def read() -> None:
        for line in stream:
            lines.append(line)
            if text in line:
                found.set()
                return

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    reader.join(timeout)
    if not found.is_set():
        why = f"within {timeout:g} s" if reader.is_alive() else "before the stream ended"
        raise AssertionError(f"{text!r} not seen {why}; lines: {''.join(list(lines))[-3000:]}")
    return lines


def start_time(pid: int) -> int | None:
    """A process's start time in clock ticks after boot (None when it is gone): tells a PID that
    was reused from the process seen before."""
    fields = _stat_fields(pid)
    if fields is None or fields[0] == "Z":  # gone, or a zombie: ended, waiting for its parent
        return None
    return int(fields[19])


def _stat_fields(pid: int) -> list[str] | None:
    """The fields of ``/proc/PID/stat`` after the command name (state, ppid, ...); None when
    the process is gone. The name may hold spaces and parentheses: split after the last ')'."""
    try:
        with open(f"/proc/{pid}/stat", encoding="utf-8") as stat:
            return stat.read().rsplit(")", 1)[1].split()
    except OSError:
        return None


def handles_signal(pid: int, signum: int) -> bool:
    """Whether process ``pid`` has a handler of its own for ``signum`` now (``SigCgt`` in
    ``/proc/PID/status``): a test that signals a child waits for this rather than a fixed time."""
    try:
        with open(f"/proc/{pid}/status", encoding="utf-8") as status:
            for line in status:
                if line.startswith("SigCgt:"):
                    return bool(int(line.split()[1], 16) >> (signum - 1) & 1)
    except OSError:
        pass
    return False


def child_environment(root: Path, domain: int) -> dict[str, str]:
    env = dict(os.environ)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["ROS_DOMAIN_ID"] = str(domain)
    env["LIT_ROOT"] = str(root)
    return env


def find_ctest_dir(root: Path) -> Path | None:
    """The core's build tree with registered tests; the newest one if there are several."""
    candidates = sorted(root.glob(CTEST_GLOB), key=lambda path: path.stat().st_mtime)
    return candidates[-1].parent if candidates else None


def sanitize_commands(root: Path, jobs: int, pybind11_dir: str | None) -> list[list[str]]:
    """Configure and build :data:`SANITIZE_DIR`: the core's library, GoogleTest binaries and,
    given ``pybind11_dir``, the extension module (in the tree's top folder, for ``PYTHONPATH``)
    with :data:`SANITIZERS`, optimised with debug information (RelWithDebInfo) for readable
    reports."""
    build = root / SANITIZE_DIR
    flags = f"{SANITIZERS} -fno-omit-frame-pointer -fno-sanitize-recover=undefined"
    python = (
        ["-DLIT_BUILD_PYTHON=ON", f"-Dpybind11_DIR={pybind11_dir}",
         f"-DPython_EXECUTABLE={sys.executable}", f"-DCMAKE_MODULE_LINKER_FLAGS={SANITIZERS}"]
        if pybind11_dir is not None else ["-DLIT_BUILD_PYTHON=OFF"]
    )  # fmt: skip
    return [
        ["cmake", "-S", str(root / "lit_planner" / "core"), "-B", str(build), *python,
         "-DLIT_INSTALL_CPP=OFF", "-DLIT_BUILD_TESTS=ON",
         "-DCMAKE_BUILD_TYPE=RelWithDebInfo", f"-DCMAKE_CXX_FLAGS={flags}",
         f"-DCMAKE_EXE_LINKER_FLAGS={SANITIZERS}"],
        ["cmake", "--build", str(build), "-j", str(jobs)],
    ]  # fmt: skip


def build_sanitized(root: Path, env: dict[str, str], python: bool = True) -> Path | str:
    """Build :data:`SANITIZE_DIR` (incremental), with the extension module when ``python``; its
    path, or what went wrong."""
    if shutil.which("cmake") is None:
        return "cmake not found on PATH (Debian package cmake)"
    pybind11_dir = None
    if python:
        try:
            import pybind11
        except ImportError:
            return "pybind11 is not installed (run ./lit once to set up)"
        pybind11_dir = pybind11.get_cmake_dir()
    built = "the C++ tests and the extension module" if python else "the C++ tests"
    print(f"lit test: building {built} with sanitizers in {SANITIZE_DIR}", flush=True)
    commands = sanitize_commands(root, os.cpu_count() or 1, pybind11_dir)
    for step, command in zip(("configuring", "building"), commands, strict=True):
        returncode = _run_runner(command, env, root)
        if returncode != 0:
            return f"{step} {SANITIZE_DIR} failed (cmake exited with {returncode})"
    return root / SANITIZE_DIR


def sanitized_python_environment(
    env: dict[str, str], build: Path, report_dir: Path
) -> dict[str, str] | str:
    """``env`` for Python tests against the sanitized extension module in ``build``, or what is
    missing: the sanitizer runtime preloaded (the Python interpreter is not built with it), with
    libstdc++ after it (ASan's interceptor of C++ exceptions finds nothing to forward to when
    libstdc++ is loaded later, with the extension), ``build`` first on ``PYTHONPATH``, and the
    reports written to :data:`SANITIZER_REPORT` files in ``report_dir`` unless the user's own
    ``ASAN_OPTIONS`` / ``UBSAN_OPTIONS`` say otherwise. The runtime is the one of the compiler
    that built ``build`` (its CMake cache's): GCC's (``CXX=clang++`` would want clang's)."""
    compiler = _cmake_compiler(build) or shutil.which("g++")
    if compiler is None or shutil.which(compiler) is None:
        return f"{compiler or 'g++'} not found (Debian package g++)"
    libraries = []
    for name in ("libasan.so", "libstdc++.so"):
        found = subprocess.run(
            [compiler, f"-print-file-name={name}"], capture_output=True, text=True, check=False
        ).stdout.strip()
        if not found or not Path(found).is_file():  # g++ prints the bare name when it has none
            return (
                f"{name} not found by {compiler} -print-file-name: --sanitize preloads GCC's "
                "runtime into Python; build with g++ (Debian package g++; remove "
                f"{SANITIZE_DIR} after changing CXX)"
            )
        libraries.append(str(Path(found).resolve()))
    sanitized = SANITIZE_PYTHON_ENV | env  # the user's own options win
    for key in SANITIZE_PYTHON_ENV:
        if key not in env:
            sanitized[key] += f":log_path={report_dir / SANITIZER_REPORT}"
    sanitized["LD_PRELOAD"] = ":".join(
        [*libraries, *filter(None, env.get("LD_PRELOAD", "").split(":"))]
    )
    paths = [str(build), *filter(None, env.get("PYTHONPATH", "").split(os.pathsep))]
    sanitized["PYTHONPATH"] = os.pathsep.join(paths)
    return sanitized


def _cmake_compiler(build: Path) -> str | None:
    """The C++ compiler a CMake build tree was configured with (``CMAKE_CXX_COMPILER``)."""
    try:
        cache = (build / "CMakeCache.txt").read_text(encoding="utf-8", errors="replace")
    except OSError:
        return None
    found = re.search(r"^CMAKE_CXX_COMPILER:\w+=(.+)$", cache, re.MULTILINE)
    return found.group(1).strip() if found else None


def sanitizer_reports(report_dir: Path) -> list[tuple[Path, str]]:
    """The :data:`SANITIZER_REPORT` files in ``report_dir`` that report an error, with their
    text (the runtime also writes warnings there, such as an unknown printf format)."""
    reports = []
    for path in sorted(report_dir.glob(f"{SANITIZER_REPORT}*")):
        text = path.read_text(encoding="utf-8", errors="replace")
        if re.search(r"ERROR: \w*Sanitizer|runtime error:|CHECK failed", text):
            reports.append((path, text))
    return reports


def run_sanitized_pytest(
    root: Path,
    env: dict[str, str],
    report_dir: Path,
    build: Path,
    keyword: str | None,
    passthrough: list[str],
) -> RunnerResult:
    """The Python tests against the sanitized extension module in ``build``:
    :data:`SANITIZE_PYTHON_TESTS`, or the test paths in ``passthrough``. Any sanitizer report
    fails the run and is printed."""
    result = RunnerResult("pytest")
    sanitized = sanitized_python_environment(env, build, report_dir)
    if isinstance(sanitized, str):
        result.error = sanitized
        return result
    try:
        probe = subprocess.run(
            [sys.executable, "-c", "import lit_core; print(lit_core.__file__)"],
            env=sanitized, capture_output=True, text=True, timeout=300, check=False, cwd=root,
        )  # fmt: skip
    except subprocess.TimeoutExpired:
        result.error = "importing the sanitized lit_core took more than 300 s"
        return result
    module = Path(probe.stdout.strip() or ".").resolve()
    if probe.returncode != 0 or module.parent != build.resolve():
        result.error = (
            f"the sanitized lit_core in {build.relative_to(root)} is not the one imported "
            f"({probe.stdout.strip() or probe.stderr.strip()[-2000:]})"
        )
        return result
    defaults, _ = _pytest_targets(root, passthrough)
    if defaults:  # no test paths given
        passthrough = [str(root / path) for path in SANITIZE_PYTHON_TESTS] + passthrough
    result = run_pytest(root, sanitized, report_dir, keyword, passthrough)
    reports = sanitizer_reports(report_dir)
    for path, text in reports:
        lines = text.splitlines()
        print(f"lit test: {path.name}:", *lines[:200], sep="\n", flush=True)
        if len(lines) > 200:
            print(f"({len(lines) - 200} more lines)", flush=True)
    if reports:  # the pytest process a report ended wrote no report of its own
        found = f"{len(reports)} sanitizer reports (printed above)"
        result.error = f"{result.error}; {found}" if result.error else found
    return result


def run_ctest(
    root: Path,
    env: dict[str, str],
    report_dir: Path,
    regex: str | None,
    build_dir: Path | None = None,
) -> RunnerResult:
    result = RunnerResult("ctest")
    build_dir = find_ctest_dir(root) if build_dir is None else build_dir
    if build_dir is None:
        result.error = f"no C++ build with tests ({CTEST_GLOB}); run ./lit once to build the core"
        return result
    ctest = shutil.which("ctest")
    if ctest is None:
        result.error = "ctest not found on PATH (Debian package cmake)"
        return result
    report = report_dir / "ctest.xml"
    command = [
        ctest,
        "--test-dir",
        str(build_dir),
        "--output-on-failure",
        "--output-junit",
        str(report),
    ]
    if regex:
        command += ["-R", regex]
    print(f"lit test: ctest in {build_dir.relative_to(root)}", flush=True)
    returncode = _run_runner(command, env, build_dir)
    if not report.is_file():
        result.error = f"ctest exited with {returncode} and wrote no report"
        return result
    for case in ElementTree.parse(report).getroot().iter("testcase"):
        status = case.get("status")
        if status == "run" and case.find("failure") is None:
            result.passed += 1
        elif status == "disabled":
            result.skipped += 1
        else:  # 'fail', 'notrun' (missing executable, failed fixture): ctest counts it as failed
            result.failed += 1
    if returncode != 0 and result.failed == 0:
        result.error = f"ctest exited with {returncode}"
    return result


def _pytest_targets(root: Path, passthrough: list[str]) -> tuple[list[str], list[str]]:
    """Split off explicit test paths (made absolute: pytest runs in the root) from other args."""
    explicit, rewritten = [], []
    for arg in passthrough:
        path, sep, rest = arg.partition("::")
        if not arg.startswith("-") and Path(path).exists():
            arg = str(Path(path).resolve()) + sep + rest
            explicit.append(arg)
        rewritten.append(arg)
    if explicit:
        return [], rewritten
    defaults = [directory for directory in PYTHON_TEST_DIRS if (root / directory).is_dir()]
    return defaults, rewritten


def _run_runner(command: list[str], env: dict[str, str], cwd: Path) -> int:
    """``subprocess.run(command)``, except that a SIGTERM or SIGHUP to ``lit test`` reaches the
    runner as the Ctrl-C it handles (pytest's fixtures then stop the nodes their tests started),
    and ``lit test`` waits for it: it ended at once, and pytest with its nodes ran on, orphaned.
    A Ctrl-C at the terminal reaches the runner itself; ``lit test`` waits for it then too."""
    process = subprocess.Popen(command, env=env, cwd=cwd)
    interrupted: list[int] = []

    def pass_on(signum: int, frame: object) -> None:
        interrupted.append(signum)
        if signum != signal.SIGINT and process.poll() is None:
            process.send_signal(signal.SIGINT)

    with signals.handling(signals.STOPS, pass_on):
        returncode = process.wait()
    if interrupted:  # no next runner: stopped as a Ctrl-C stops it
        raise KeyboardInterrupt
    return returncode


def run_pytest(
    root: Path, env: dict[str, str], report_dir: Path, keyword: str | None, passthrough: list[str]
) -> RunnerResult:
    result = RunnerResult("pytest")
    targets, extra = _pytest_targets(root, passthrough)
    if not targets and not extra:
        print("lit test: no Python test directories", flush=True)
        return result
    report = report_dir / "pytest.xml"
    # Default (prepend) import mode: test module basenames must be unique across the test
    # directories. importlib mode would lift that, but it registers `lit_planner`, `lit_msgs_json`
    # as parents of the test modules and so hides the real packages.
    # A test still running after PYTEST_HANG_DUMP_S has every thread's stack printed (pytest's own
    # faulthandler plugin; it does not stop the test), so a hung run shows where it hangs.
    command = [
        sys.executable,
        "-m",
        "pytest",
        "-q",
        f"--junitxml={report}",
        "-o",
        f"faulthandler_timeout={PYTEST_HANG_DUMP_S}",
    ]
    if keyword:
        command += ["-k", keyword]
    command += targets + extra
    print(f"lit test: pytest {' '.join(targets + extra)}", flush=True)
    returncode = _run_runner(command, env, root)
    if returncode == 5:  # pytest: no tests collected
        return result
    if not report.is_file():
        result.error = f"pytest exited with {returncode} and wrote no report"
        return result
    for suite in ElementTree.parse(report).getroot().iter("testsuite"):
        tests, skipped = int(suite.get("tests", 0)), int(suite.get("skipped", 0))
        failed = int(suite.get("failures", 0)) + int(suite.get("errors", 0))
        result.failed += failed
        result.skipped += skipped
        result.passed += tests - failed - skipped
    if returncode not in (0, 1) or (returncode == 1 and result.failed == 0):
        result.error = f"pytest exited with {returncode}"
    return result


def main(args: argparse.Namespace) -> int:
    """Run the tests selected by ``args``; the exit status of ``lit test``."""
    root = repo_root()
    domain, domain_lock = reserve_ros_domain()
    env = child_environment(root, domain)
    print(f"lit test: ROS_DOMAIN_ID={domain}, ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST", flush=True)
    try:
        with tempfile.TemporaryDirectory(prefix="lit-test-") as tmp:
            report_dir = Path(tmp)
            if args.sanitize:
                ctest, pytest = RunnerResult("ctest"), RunnerResult("pytest")
                built = build_sanitized(root, env, python=not args.no_pytest)
                if isinstance(built, str):
                    ctest.error = built
                else:
                    if not args.no_ctest:
                        sanitized = SANITIZE_ENV | env  # the user's own options win
                        ctest = run_ctest(root, sanitized, report_dir, args.ctest_regex, built)
                    if not args.no_pytest:
                        pytest = run_sanitized_pytest(
                            root, env, report_dir, built, args.keyword, args.pytest_args
                        )
            else:
                ctest = (
                    RunnerResult("ctest")
                    if args.no_ctest
                    else run_ctest(root, env, report_dir, args.ctest_regex)
                )
                pytest = (
                    RunnerResult("pytest")
                    if args.no_pytest
                    else run_pytest(root, env, report_dir, args.keyword, args.pytest_args)
                )
    finally:
        if domain_lock is not None:
            domain_lock.close()

    results = (ctest, pytest)
    for result in results:
        if result.skipped:
            print(f"lit test: {result.name}: {result.skipped} skipped")
        if result.error:
            print(f"lit test: {result.name}: {result.error}")
    passed = sum(result.passed for result in results)
    failed = sum(result.failed for result in results)
    if passed + failed == 0:
        print("lit test: no test ran")
    print(
        f"lit test: {passed} passed, {failed} failed "
        f"(ctest {ctest.passed}/{ctest.ran}, pytest {pytest.passed}/{pytest.ran})",
        flush=True,
    )
    broken = any(result.error for result in results)
    return 1 if failed or broken or passed + failed == 0 else 0
