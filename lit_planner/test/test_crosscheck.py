"""``lit crosscheck``: LIT*'s paths and costs against OMPL 2.0.1 and an independent checker.

The OMPL 2.0.1 side runs in its own process (PyPI ompl must not meet lit_core); these tests check
that it does, that it catches invalid paths and mis-reported costs, and run one short real
cross-check on np4.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from lit_planner import crosscheck, ompl2, scenarios


def test_agreement_rule() -> None:
    assert crosscheck.agree(0.46, 0.44, 0.10)
    assert crosscheck.agree(0.44, 0.46, 0.10)  # symmetric
    assert not crosscheck.agree(0.61, 0.45, 0.10)
    assert crosscheck.agree(1.0, 1.099, 0.10) and not crosscheck.agree(1.0, 1.101, 0.10)
    assert not crosscheck.agree(None, 0.5, 0.10)  # a planner without a solution never agrees
    assert not crosscheck.agree(math.inf, 0.5, 0.10)


def test_worker_revalidates_paths_in_its_own_process() -> None:
    scenario = scenarios.get("np4")
    through_slab = [scenario.start, (-0.1, 0.1, 0.0, 0.0), (0.1, 0.1, 0.0, 0.0), scenario.goal]
    length = scenarios.check_path(scenario, through_slab).cost
    response = ompl2.run_worker("crosscheck", {
        "scenario": scenario.to_dict(),
        "paths": [
            {"label": "straight", "path": [scenario.start, scenario.goal], "cost": 0.4},
            {"label": "slab", "path": through_slab, "cost": length},
            {"label": "slab, wrong cost", "path": through_slab, "cost": length - 0.01},
            {"label": "slab, not to the goal", "path": through_slab[:-1], "cost": length - 0.1},
        ],
        "planners": [], "runs": 0, "time": 1.0, "seed": 1,
    }, capture_stderr=True)  # fmt: skip
    assert response["process"]["pid"] != os.getpid()
    assert response["process"]["lit_core_loaded"] is False
    assert response["process"]["ompl_version"] == "2.0.1"
    straight, slab, wrong_cost, short = response["validations"]
    assert not straight["valid"] and not straight["ompl_motion_valid"]
    assert straight["ompl_first_invalid_segment"] == 0 and not straight["dense_valid"]
    assert slab["valid"] and slab["ompl_motion_valid"] and slab["dense_valid"]
    assert slab["length"] == pytest.approx(length, rel=1e-12)
    assert not wrong_cost["valid"] and wrong_cost["ompl_motion_valid"]
    assert not wrong_cost["cost_matches"]
    assert not short["valid"] and short["dense"]["ends_at_goal"] is False


def test_verdict_of_an_invalid_path_and_a_disagreement() -> None:
    scenario = scenarios.get("np4")

    def run(planner: str, cost: float, valid: bool = True) -> dict[str, Any]:
        return {"planner": planner, "solved": True, "c_final": cost,
                "validation": {"valid": valid}}  # fmt: skip

    rows = crosscheck._rows(scenario, "litstar-fixed", [run("litstar-fixed", 0.45, valid=False)],
                            [run("bitstar", 0.46), run("irrtstar", 0.60)],
                            ["bitstar", "irrtstar"], 0.10)  # fmt: skip
    lit, bitstar, irrtstar = rows
    assert lit["paths_valid"] == 0 and not lit["ok"]
    assert bitstar["agrees"] and bitstar["ok"]
    assert not irrtstar["agrees"] and not irrtstar["ok"]
    assert irrtstar["difference"] == pytest.approx((0.60 - 0.45) / 0.45)
    report = {"ok": False, "tolerance": 0.10, "time": 5.0, "runs": 1,
              "litstar": "litstar-fixed", "rows": rows}  # fmt: skip
    text = crosscheck.format_table(report)
    assert "FAILED: 1 invalid path(s)" in text
    assert "best costs disagree: np4 OMPL 2.0.1 Informed RRT*" in text
    assert "Known optima: np4 0.4236 (NP's is the infimum through the slab)." in text
    # The note on the optima names the families in the table (it called WG's value NP's).
    others = [crosscheck._row(scenarios.get(name), "irrtstar", "x", [run("irrtstar", 1.0)])
              for name in ("wg4", "rrd4")]  # fmt: skip
    text = crosscheck.format_table(dict(report, rows=others))
    assert ("Known optima: wg4 0.6308 (WG's the infimum through the gap; random scenarios have "
            "none).") in text  # fmt: skip
    below = crosscheck._row(scenario, "bitstar", "x", [run("bitstar", 0.40)])
    assert below["below_optimum"] and not below["ok"]  # np4's optimum is 0.4236

    # Nothing solved on one side: the verdict says so (its line used to end "FAILED: ").
    unsolved = {"planner": "irrtstar", "solved": False, "c_final": None, "validation": None}
    rows = crosscheck._rows(scenario, "litstar-fixed", [run("litstar-fixed", 0.45)], [unsolved],
                            ["irrtstar"], 0.10)  # fmt: skip
    text = crosscheck.format_table(dict(report, rows=rows))
    assert text.endswith("FAILED: no best costs to compare (no solution in LIT*'s runs, the "
                         "planner's, or both): np4 OMPL 2.0.1 Informed RRT*"), text  # fmt: skip


def test_short_real_crosscheck_on_np4(tmp_path: Path) -> None:
    """One run of each planner; a huge tolerance: here only validity is judged. (2 s each: OMPL
    2.0.1's BIT* with its Python checker solves np4 in well under 0.5 s here, and must solve it
    on a loaded machine too.) The report goes into a folder that does not exist yet (it ended the
    run with a traceback)."""
    out = tmp_path / "new" / "crosscheck.json"
    process = subprocess.run(
        [sys.executable, "-m", "lit_planner.cli", "crosscheck", "--scenarios", "np4",
         "--runs", "1", "--time", "2", "--tolerance", "100", "--json", str(out)],
        capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert process.returncode == 0, process.stdout + process.stderr
    assert "| np4 | litstar-fixed | 1 | 1 | 1/1 |" in process.stdout
    assert "| np4 | OMPL 2.0.1 BIT* | 1 | 1 | 1/1 |" in process.stdout
    assert "| np4 | OMPL 2.0.1 Informed RRT* | 1 |" in process.stdout
    assert "Known optima: np4 0.4236" in process.stdout
    report = json.loads(out.read_text())
    assert report["ok"] is True
    assert crosscheck._is_report(out)  # a next run with this --json replaces it
    (detail,) = report["scenarios"]
    assert detail["ompl2_process"]["lit_core_loaded"] is False
    assert detail["ompl2_process"]["pid"] != os.getpid()
    (lit_run,) = detail["litstar_runs"]
    validation = lit_run["validation"]
    assert validation["valid"] and validation["ompl_motion_valid"] and validation["dense_valid"]
    assert validation["length"] == pytest.approx(lit_run["c_final"], rel=1e-9)
    assert {run["planner"] for run in detail["ompl2_runs"]} == {"bitstar", "irrtstar"}
    for run in detail["ompl2_runs"]:
        if run["solved"]:
            assert run["validation"]["valid"]
            assert run["c_final"] >= scenarios.get("np4").optimal_cost


def test_a_json_file_that_is_not_a_report_is_not_written_over(tmp_path: Path) -> None:
    """`--json world.json` given by mistake replaced the world file with the report."""
    world = tmp_path / "world.json"
    world.write_text('{"lower": [0, 0], "upper": [1, 1], "boxes": []}')
    process = subprocess.run(
        [sys.executable, "-m", "lit_planner.cli", "crosscheck", "--scenarios", "np4",
         "--runs", "1", "--json", str(world)],
        capture_output=True, text=True, timeout=60, check=False,
    )  # fmt: skip
    assert process.returncode == 2, process.stderr
    assert "there, and not a lit crosscheck report (which is replaced)" in process.stderr
    assert world.read_text() == '{"lower": [0, 0], "upper": [1, 1], "boxes": []}'


def test_bad_arguments_exit_2() -> None:
    process = subprocess.run(
        [sys.executable, "-m", "lit_planner.cli", "crosscheck", "--scenarios", "np4",
         "--planners", "rrtconnect"],
        capture_output=True, text=True, timeout=60, check=False,
    )  # fmt: skip
    assert process.returncode == 2
    assert "OMPL 2.0.1 planners must be among bitstar, irrtstar" in process.stderr
    process = subprocess.run(
        [sys.executable, "-m", "lit_planner.cli", "crosscheck", "--runs", "5000000000"],
        capture_output=True, text=True, timeout=60, check=False,
    )  # fmt: skip
    # Refused at once (a check per seed ran for minutes before it reached the largest seed).
    assert process.returncode == 2, process.stderr
    assert "--runs 5000000000 from seed 1 reaches seed 5000000000, beyond the largest" in (
        process.stderr
    )
    # A name given twice ran twice and each row pooled both runs ("2 | 2 | 2/2" under a header
    # of one run per planner), every row printed twice, exit 0.
    for option, value, label in (
        ("--scenarios", "np4,np4", "scenario given twice: np4"),
        ("--scenarios", "np4,np4/0", "scenario given twice: np4"),  # instance 0 is np4 itself
        ("--planners", "bitstar,bitstar", "planner given twice: bitstar"),
        # Refused by the first plan, after the run's first line had been printed.
        ("--time", "1e12", "--time must be at most 1e+09 s, got 1e+12"),
    ):
        process = subprocess.run(
            [sys.executable, "-m", "lit_planner.cli", "crosscheck", option, value, "--runs", "1"],
            capture_output=True, text=True, timeout=60, check=False,
        )  # fmt: skip
        assert process.returncode == 2, process.stderr
        assert label in process.stderr, process.stderr
        assert process.stdout == "" and "lit crosscheck: np4" not in process.stderr, process
    # The tensors of litstar-tensor: named, and checked before the first run (a missing folder
    # was reported after the first run's progress line); refused for another variant.
    for options, message in (
        (["--litstar", "litstar-tensor", "--tensors", "/nonexistent-lit"], "/nonexistent-lit"),
        (["--tensors", "tensors"], "--tensors is for --litstar litstar-tensor, not litstar-fixed"),
    ):
        process = subprocess.run(
            [sys.executable, "-m", "lit_planner.cli", "crosscheck", "--runs", "1", *options],
            capture_output=True, text=True, timeout=60, check=False,
        )  # fmt: skip
        assert process.returncode == 2, process.stderr
        assert message in process.stderr and "seed 1" not in process.stderr, process.stderr
