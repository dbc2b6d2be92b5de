"""Worker: OMPL benchmark log files to a Planner Arena SQLite database, with PyPI ompl's converter.

PyPI ``ompl`` 2.0.1 ships OMPL's own converter, the functions behind ``ompl_benchmark_statistics.py``:
``ompl.tools.readBenchmarkLog(dbname, filenames, moveitformat)`` parses the logs into the tables
``experiments``, ``plannerConfigs``, ``runs``, ``progress`` and ``enums``, and
``ompl.tools.computeViews(dbname, moveitformat)`` adds the views ``bestPlannerConfigs`` and
``bestPlannerConfigsPerExperiment`` that Planner Arena reads. This worker calls exactly those.

Request: ``{"logs": [paths], "database": path, "append": false}``. Response: ``{"database",
"converter", "tables", "views", "rows", "converter_output"}`` plus the process report.
Run it through :func:`lit_planner.ompl2.run_worker`, never by importing it beside ``lit_core``.
"""

from __future__ import annotations

import contextlib
import io
import sqlite3
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from lit_planner.ompl2 import worker_main

CONVERTER = "ompl.tools.readBenchmarkLog + ompl.tools.computeViews (PyPI ompl)"
"""What this worker uses, as reported in its response."""


def convert(request: Mapping[str, Any]) -> dict[str, Any]:
    """Convert the request's logs into its database (replaced unless ``append``)."""
    from ompl import tools  # only here: enter_worker has checked the process first

    logs = [str(Path(path)) for path in request["logs"]]
    if not logs:
        raise ValueError("no benchmark log files to convert")
    missing = [path for path in logs if not Path(path).is_file()]
    if missing:
        raise FileNotFoundError(f"benchmark logs not found: {', '.join(missing)}")
    database = Path(request["database"])
    if database.exists() and not request.get("append", False):
        database.unlink()
    output = io.StringIO()
    with contextlib.redirect_stdout(output):  # the converter prints one line per log and planner
        tools.readBenchmarkLog(str(database), logs, False)
        tools.computeViews(str(database), False)
    with contextlib.closing(sqlite3.connect(database)) as connection:
        entries = connection.execute("SELECT type, name FROM sqlite_master").fetchall()
        tables = sorted(name for kind, name in entries
                        if kind == "table" and not name.startswith("sqlite_"))  # fmt: skip
        views = sorted(name for kind, name in entries if kind == "view")
        rows = {table: connection.execute(f'SELECT COUNT(*) FROM "{table}"').fetchone()[0]
                for table in tables}  # fmt: skip
    return {
        "database": str(database),
        "converter": CONVERTER,
        "tables": tables,
        "views": views,
        "rows": rows,
        "converter_output": output.getvalue().splitlines(),
    }


if __name__ == "__main__":
    worker_main("arena_db", convert)
