"""Tuning and robustness sweeps: parallel, resumable, watched, summarised.

A sweep is the grid of runs (scenario, ``--set`` settings, g, q, seed), plus
auto mode (g = q = auto) when asked for.  The package keeps one concept per
module:

- :mod:`~sim.tune.spec`: one run (:class:`RunSpec`, :func:`run_one`) and the
  grids of runs;
- :mod:`~sim.tune.results`: the JSON Lines results file, and which files a
  sweep may append to;
- :mod:`~sim.tune.driver`, :mod:`~sim.tune.pool`, :mod:`~sim.tune.cluster`:
  running the runs not yet in the file on local worker processes or a Dask
  cluster, each under a watchdog;
- :mod:`~sim.tune.summary`, :mod:`~sim.tune.robustness`: the tables (per
  setting, the paper's Tables II and III, contact rates with Wilson
  intervals, margins needed);
- :mod:`~sim.tune.plots`, :mod:`~sim.tune.report`: heatmaps, contact-rate
  plots, ``NAME.md`` and the page ``NAME.html``;
- :mod:`~sim.tune.cli`: ``swarmform tune``.

Example (about a second on two cores)::

    from sim.scenario import read_scenario
    from sim.tune import grid, sweep, write_summary

    specs = grid([read_scenario("scenarios/paper/fig2-random-to-C.yaml")], g=[1, 2], q=[50], seeds=range(3))
    sweep(specs, "media/fig2.jsonl", workers=2)   # 6 rows; a rerun computes nothing
    write_summary("media/fig2.jsonl")             # media/fig2.md, .html and the heatmap
"""

from ..lazy import lazy_exports

# name -> the module that defines it; imported on first use, so that building
# the command line (``swarmform --help``) loads neither the planner nor Dask.
_WHERE = {
    **dict.fromkeys(("EXIT_CLUSTER_LOST", "add_tune_parser"), "cli"),
    "ClusterLostError": "cluster",
    **dict.fromkeys(("SweepResult", "sweep", "watchdog_s"), "driver"),
    **dict.fromkeys(("BUILD_ALLOWANCE_S", "PHYSICS_ALLOWANCE_S", "TIMEOUT", "WORKER_DIED"), "limits"),
    "write_summary": "report",
    **dict.fromkeys(("ResultsFile", "check_output", "read_results"), "results"),
    **dict.fromkeys(("RobustCell", "margin_needed", "robustness_blocks", "robustness_cells", "wilson_interval"),
                    "robustness"),
    **dict.fromkeys(("KEY_FIELDS", "PAPER_DIR", "VOLATILE_FIELDS", "RunSpec", "TuneError", "failure_row", "grid",
                     "paper_grid", "read_variants", "run_one"), "spec"),
    **dict.fromkeys(("paper_table", "summarize"), "summary"),
}

__all__ = [
    "BUILD_ALLOWANCE_S",
    "EXIT_CLUSTER_LOST",
    "KEY_FIELDS",
    "PAPER_DIR",
    "PHYSICS_ALLOWANCE_S",
    "TIMEOUT",
    "VOLATILE_FIELDS",
    "WORKER_DIED",
    "ClusterLostError",
    "ResultsFile",
    "RobustCell",
    "RunSpec",
    "SweepResult",
    "TuneError",
    "add_tune_parser",
    "check_output",
    "failure_row",
    "grid",
    "margin_needed",
    "paper_grid",
    "paper_table",
    "read_results",
    "read_variants",
    "robustness_blocks",
    "robustness_cells",
    "run_one",
    "summarize",
    "sweep",
    "watchdog_s",
    "wilson_interval",
    "write_summary",
]


__getattr__, __dir__ = lazy_exports(__name__, _WHERE)
