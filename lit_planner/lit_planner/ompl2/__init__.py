"""Everything that uses PyPI ``ompl`` (OMPL 2.0.1), each piece run in a process of its own.

PyPI ``ompl`` and our ``lit_core`` (linked to Debian's OMPL 1.5.2) load side by side without
crashing, but they share Boost.Serialization singletons, so they must never live in one process.
The modules here that import ``ompl`` are workers: the parent calls :func:`run_worker`, which
starts ``python -m lit_planner.ompl2.<worker> REQUEST.json RESPONSE.json``; the worker calls
:func:`enter_worker` before importing ``ompl``, which refuses to run when ``lit_core`` is already
loaded and blocks any later import of it. Every response carries :func:`process_report`, so
callers (and tests) can see that the work happened in a separate process without ``lit_core``.

Workers: :mod:`~lit_planner.ompl2.arena_db` (benchmark logs to a Planner Arena database) and
:mod:`~lit_planner.ompl2.crosscheck` (OMPL 2.0.1's planners and the independent path check). This
package's ``__init__`` and :mod:`~lit_planner.ompl2.checker` import no ``ompl``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from lit_planner.errors import LitPlannerError

FORBIDDEN_MODULE = "lit_core"
"""The module that must not share a process with PyPI ``ompl``."""
WORKERS = ("arena_db", "crosscheck")
"""Modules of this package that :func:`run_worker` may start."""


class Ompl2Error(LitPlannerError):
    """A PyPI-ompl worker refused to run, failed, or answered something unreadable."""


def enter_worker(worker: str) -> None:
    """Call first in a worker: refuse to run beside ``lit_core``, and keep it out from now on.

    Raises:
        Ompl2Error: ``lit_core`` is already imported in this process.
    """
    if sys.modules.get(FORBIDDEN_MODULE) is not None:
        raise Ompl2Error(
            f"lit_planner.ompl2.{worker} imports PyPI ompl and must not run in a process that "
            f"has imported {FORBIDDEN_MODULE} (Debian OMPL 1.5.2): they share Boost.Serialization "
            "singletons. Start it with lit_planner.ompl2.run_worker"
        )
    sys.modules[FORBIDDEN_MODULE] = None  # type: ignore[assignment]  # a later import raises


def process_report() -> dict[str, Any]:
    """Facts about the current process that show where the work ran."""
    ompl = sys.modules.get("ompl")
    version = None
    if ompl is not None:
        from importlib import metadata

        try:
            version = metadata.version("ompl")
        except metadata.PackageNotFoundError:
            version = None
    return {
        "pid": os.getpid(),
        "python": sys.executable,
        "lit_core_loaded": sys.modules.get(FORBIDDEN_MODULE) is not None,
        "ompl_loaded": ompl is not None,
        "ompl_version": version,
        "ompl_file": getattr(ompl, "__file__", None),
    }


def run_worker(
    worker: str,
    request: Mapping[str, Any],
    *,
    timeout: float | None = None,
    capture_stderr: bool = False,
) -> dict[str, Any]:
    """Run ``lit_planner.ompl2.<worker>`` in a new Python process and return its response.

    Args:
        worker: one of :data:`WORKERS`.
        request: JSON-able request for the worker.
        timeout: seconds before the worker is killed (None: no limit).
        capture_stderr: keep the worker's stderr (shown only if it fails) instead of passing it
            through to ours (its progress lines).

    Raises:
        Ompl2Error: unknown worker, the worker exited non-zero, timed out or wrote no response.
    """
    if worker not in WORKERS:
        raise Ompl2Error(f"unknown ompl2 worker {worker!r}; expected one of {', '.join(WORKERS)}")
    with tempfile.TemporaryDirectory(prefix=f"lit-ompl2-{worker}-") as tmp:
        request_path, response_path = Path(tmp) / "request.json", Path(tmp) / "response.json"
        request_path.write_text(json.dumps(request, allow_nan=False))
        command = [sys.executable, "-m", f"lit_planner.ompl2.{worker}",
                   str(request_path), str(response_path)]  # fmt: skip
        try:
            process = subprocess.run(
                command,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE if capture_stderr else None,
                text=True,
                timeout=timeout,
                check=False,
            )
        except subprocess.TimeoutExpired as error:
            raise Ompl2Error(f"ompl2 worker {worker} did not finish within {timeout} s") from error
        details = f": {process.stderr.strip()[-2000:]}" if capture_stderr and process.stderr else ""
        response: dict[str, Any] | None = None
        if response_path.is_file():
            try:
                response = json.loads(response_path.read_text())
            except json.JSONDecodeError as error:
                raise Ompl2Error(f"ompl2 worker {worker} wrote unreadable JSON: {error}") from error
        if process.returncode != 0:
            reason = f": {response['error']}" if response and response.get("error") else details
            raise Ompl2Error(f"ompl2 worker {worker} exited with {process.returncode}{reason}")
        if response is None:
            raise Ompl2Error(f"ompl2 worker {worker} wrote no response{details}")
    return response


def worker_main(worker: str, handle: Any, argv: list[str] | None = None) -> None:
    """Entry point of a worker module: read the request, ``handle`` it, write the response.

    Ends the process with ``os._exit`` after flushing, which skips nanobind's leak report at
    interpreter shutdown (OMPL's objects are owned on the C++ side; the report is noise).
    Exit status 0 on success, 1 on a handled error (also written as ``{"error": ...}``), 2 on a
    wrong command line.
    """
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 2:
        print(f"usage: python -m lit_planner.ompl2.{worker} REQUEST.json RESPONSE.json",
              file=sys.stderr)  # fmt: skip
        sys.exit(2)
    request_path, response_path = Path(args[0]), Path(args[1])
    status = 0
    try:
        enter_worker(worker)
        response = dict(handle(json.loads(request_path.read_text())))
    except Exception as error:  # noqa: BLE001 -- any failure becomes the worker's answer
        print(f"lit_planner.ompl2.{worker}: {type(error).__name__}: {error}", file=sys.stderr)
        response, status = {"error": f"{type(error).__name__}: {error}"}, 1
    response["process"] = process_report()
    response_path.write_text(json.dumps(response, allow_nan=False))
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)
