"""How the first batch's size B changes the search up to the first solution: LIT* with the fixed
policy (psi_K = e) at several B against FIT*, on the development queries (never the benchmark's
seeds 1-100). Each query stops at its first solution; the table gives the medians of the validity
checks up to it (a function of the seed and the policy, free of timing noise) and of c_init, with
the number of queries solved within the scenario's budget.

    .venv/bin/python lit_planner/examples/first_batch_checks.py   # about 20 s on 2 cores

README's Policies section shows its table of 2026-12-07.
"""

from __future__ import annotations

import argparse
import statistics

import lit_core

from lit_planner import planning

SCENARIOS = ("np4", "np8", "np16", "rrd4", "rrd8", "rrd16")


class _StopAtFirst:
    """A listener that ends the solve at its first solution."""

    def __init__(self, flag: lit_core.CancelFlag) -> None:
        self.flag = flag

    def on_solution(self, event: object) -> None:
        self.flag.set()


def first_solutions(name: str, policy: str, params: dict[str, int], seeds: range) -> list[tuple]:
    """(checks up to the first solution, c_init) of each query solved within the budget."""
    found = []
    for seed in seeds:
        flag = lit_core.CancelFlag()
        result = planning.plan(
            name, "litstar", policy, seed=seed, params=params, listener=_StopAtFirst(flag),
            cancel=flag, check_path=False, features=False,
        )  # fmt: skip
        if result["checks_init"] is not None:
            found.append((result["checks_init"], result["c_init"]))
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--first-seed", type=int, default=3000, help="default: %(default)s")
    parser.add_argument("--queries", type=int, default=30, help="default: %(default)s")
    parser.add_argument("--instance", type=int, default=7, help="of rrd (default: %(default)s)")
    parser.add_argument("--batch-sizes", default="25,50,100,200", help="default: %(default)s")
    args = parser.parse_args()
    lit_core.set_log_level("warn")
    sizes = [int(b) for b in args.batch_sizes.split(",")]
    configs = [("FIT*", "fit", {})] + [(f"B = {b}", "fixed", {"batch_size": b}) for b in sizes]
    seeds = range(args.first_seed, args.first_seed + args.queries)
    print("| scenario | " + " | ".join(label for label, _, _ in configs) + " |")
    print("| --- |" + " --- |" * len(configs))
    for scenario in SCENARIOS:
        name = f"{scenario}/{args.instance}" if scenario.startswith("rrd") else scenario
        cells = []
        for _, policy, params in configs:
            found = first_solutions(name, policy, params, seeds)
            checks = statistics.median(c for c, _ in found) / 1e3 if found else float("nan")
            cost = statistics.median(c for _, c in found) if found else float("nan")
            cells.append(f"{checks:.0f}k / {cost:.3f} ({len(found)})")
        print(f"| {scenario} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
