"""``ros2_ws/`` builds the three ament_python packages and the C++ core (``lit_core``, a cmake
package) with colcon (no ROS install needed).

What a ROS user gets from ``colcon build``: each package installed under ``install/<pkg>``, its
marker in the ament resource index, its ``package.xml`` in ``share/<pkg>``, the node executables in
``lib/<pkg>`` where ``ros2 run <pkg> <exe>`` looks for them, and the ``lit_core`` extension module
that ``source install/setup.bash`` puts on the Python path.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CORE = ROOT / "lit_planner" / "core"
PACKAGES = {
    "lit_msgs_json": [],
    "lit_learner": ["lit_learner_node"],
    "lit_planner": ["lit_planner_node", "lit_recorder_node"],
}


def test_colcon_builds_the_workspace(tmp_path: Path) -> None:
    colcon = Path(sys.executable).parent / "colcon"
    assert colcon.exists(), "colcon is part of requirements.lock"
    env = dict(os.environ, COLCON_HOME=str(tmp_path / "colcon_home"))
    before = _source_tree_status()
    process = subprocess.run(
        [
            str(colcon), "--log-base", str(tmp_path / "log"), "build",
            "--base-paths", str(ROOT / "ros2_ws" / "src"),
            "--build-base", str(tmp_path / "build"),
            "--install-base", str(tmp_path / "install"),
            # The GoogleTest binaries are ctest's business (lit test builds them); the interpreter
            # is this one, whose pip pybind11 the core's CMake finds by asking it.
            "--cmake-args", "-DLIT_BUILD_TESTS=OFF", f"-DPython_EXECUTABLE={sys.executable}",
        ],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=1200, check=False,
    )  # fmt: skip
    assert process.returncode == 0, process.stdout[-3000:] + process.stderr[-3000:]
    output = process.stdout + process.stderr
    for package in [*PACKAGES, "lit_core"]:
        assert f"Finished <<< {package}" in output, output[-2000:]
    install = tmp_path / "install"
    for package, executables in PACKAGES.items():
        prefix = install / package
        assert (prefix / "share/ament_index/resource_index/packages" / package).is_file()
        assert (prefix / "share" / package / "package.xml").is_file()
        site = next(prefix.glob("lib/python3*/site-packages"))
        assert (site / package / "__init__.py").is_file()
        for executable in executables:
            script = prefix / "lib" / package / executable
            assert script.is_file() and os.access(script, os.X_OK), script
            assert f"'{executable}'" in script.read_text()  # the console-script entry
    # The C++ core: its module under site-packages, found after sourcing the workspace (colcon
    # from PyPI writes setup.sh; a ROS install adds setup.bash).
    assert list((install / "lit_core").glob("lib/python3*/site-packages/lit_core*.so"))
    probe = subprocess.run(
        ["sh", "-c", (f". {install}/setup.sh && {sys.executable} -c "
                      "'import lit_core; print(lit_core.__file__); print(lit_core.LookupTensor)'")],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert probe.returncode == 0, probe.stdout + probe.stderr
    assert probe.stdout.startswith(str(install / "lit_core")), probe.stdout
    _check_cpp_consumer(install, tmp_path, env)
    # The build works on copies: the source tree is left as it was, ignored files included (a
    # build/ or *.egg-info/ written into a package is in .gitignore; bytecode caches aside).
    written = [line for line in _source_tree_status() - before if "__pycache__" not in line]
    assert written == [], written


def _source_tree_status() -> set[str]:
    """``git status`` of the workspace and the packages, listing ignored files too."""
    status = subprocess.run(
        ["git", "status", "--porcelain", "--ignored", "--", "ros2_ws", *PACKAGES],
        cwd=ROOT, capture_output=True, text=True, check=True,
    )  # fmt: skip
    return set(status.stdout.splitlines())


def _check_cpp_consumer(install: Path, tmp_path: Path, env: dict[str, str]) -> None:
    """The C++ library as another CMake project uses it: ``find_package(lit_core)`` in the sourced
    workspace finds the installed headers, library and ``lit::core``; the example built against
    them plans np8 with the shipped tensors and finds the first solution the extension module finds
    for the same seed (the same planner, whichever way it is built)."""
    from lit_planner import planning

    lib = install / "lit_core"
    assert (lib / "include/lit/LITstar.h").is_file()
    assert (lib / "lib/cmake/lit_core/lit_coreConfig.cmake").is_file()
    # OMPL's paths come from the consumer's find_package(ompl), not from this build's machine.
    targets = (lib / "lib/cmake/lit_core/lit_coreTargets.cmake").read_text()
    assert "ompl-1.5" not in targets and "libompl" not in targets, targets
    build = tmp_path / "example"
    script = (
        f". {install}/setup.sh && cmake -S {CORE / 'examples'} -B {build} "
        f"&& cmake --build {build} && {build}/plan_narrow_passage {ROOT / 'tensors'} 0.2 1"
    )
    process = subprocess.run(
        ["sh", "-c", script], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600,
        check=False,
    )  # fmt: skip
    assert process.returncode == 0, process.stdout[-3000:] + process.stderr[-3000:]
    assert "policy tensor, 8-D narrow passage" in process.stdout, process.stdout[-2000:]
    assert "Exact solution" in process.stdout, process.stdout[-2000:]
    reference = planning.plan(
        "np8", "litstar", policy="tensor", seed=1, time=0.2, tensors_dir=ROOT / "tensors"
    )
    # The same search: the example decides psi_K every 10 expansions, as the Python side does
    # from the shipped k_tensor.json (with another interval the search differs), so the first
    # solution comes at the same iteration with the same cost.
    first = f"(iteration {reference['iteration_init']}), cost {reference['c_init']:.4f};"
    assert first in process.stdout, process.stdout[-2000:]
    # ... and the comparison tells intervals apart: at every expansion the first solution comes
    # at another iteration (on this query its cost happens to be the same).
    every = subprocess.run(
        ["sh", "-c", f". {install}/setup.sh && {build}/plan_narrow_passage {ROOT / 'tensors'} 0.2 1 1"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600, check=False,
    )  # fmt: skip
    assert every.returncode == 0 and "Exact solution" in every.stdout, every.stdout + every.stderr
    assert first not in every.stdout, every.stdout
    # A bad argument is named (std::stod's own message was only "stod").
    for arguments, message in (
        ("0.2x", "SECONDS must be a number, got '0.2x'"),
        ("0.2 1.5", "SEED must be a whole number, got '1.5'"),
        ("-1", "SECONDS must be positive and at most 1e9, got -1"),
        ("2e9", "SECONDS must be positive and at most 1e9, got 2e9"),  # OMPL's stop overflows
    ):
        bad = subprocess.run(
            ["sh", "-c", f". {install}/setup.sh && {build}/plan_narrow_passage {ROOT / 'tensors'} {arguments}"],
            cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600, check=False,
        )  # fmt: skip
        assert bad.returncode == 2, bad.stdout + bad.stderr
        assert bad.stderr.strip() == f"plan_narrow_passage: {message}", bad.stderr
    # A folder without tensors is named by its first file (GCC's argument order named the second).
    empty = tmp_path / "no-tensors"
    empty.mkdir()
    missing = subprocess.run(
        ["sh", "-c", f". {install}/setup.sh && {build}/plan_narrow_passage {empty} 0.2"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600, check=False,
    )  # fmt: skip
    assert missing.returncode == 2, missing.stdout + missing.stderr
    assert f"'{empty}/b_tensor.npy': cannot be opened" in missing.stderr, missing.stderr
