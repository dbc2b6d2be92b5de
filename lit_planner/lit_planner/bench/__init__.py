"""``lit bench``: benchmarks in the manner of the Planner Developer Tools (PDT).

- :mod:`~lit_planner.bench.runner`: runs every planner on every scenario, one record per run;
- :mod:`~lit_planner.bench.stats`: medians with binomial confidence intervals, cost over time;
- :mod:`~lit_planner.bench.report`: statistics per scenario and planner, the comparison tables,
  ``summary.json`` content and ``summary.md``;
- :mod:`~lit_planner.bench.plots`: the per-scenario figures;
- :mod:`~lit_planner.bench.environment`: machine and versions;
- :mod:`~lit_planner.bench.cli`: the ``lit bench`` command.
"""
