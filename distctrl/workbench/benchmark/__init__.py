"""The height-control benchmark (issue 41, ``distctrl benchmark``, docs/benchmark.md).

The modules, by role (each imports only those before it; this face re-exports the public names):

* :mod:`.suite`: :class:`SuiteParams`, the plates (:func:`plates`), the runs (:class:`RunSpec`,
  :func:`runs`) and each run's scenario for the simulator (:func:`scenario_dict`);
* :mod:`.contestants`: the contestants, each running a RunSpec into a :class:`Track`;
* :mod:`.metrics`: the figures of a run (:func:`measure`);
* :mod:`.output`: CSV, one plot per plate, the HTML report, the text summary;
* :mod:`.run`: :func:`run_suite` (in this process or on a dask cluster), :class:`BenchmarkResult`,
  the reproduction check and issue 41's goals.
"""
from .contestants import PID_GAINS, PROCESS_FUNCTIONS, Track, run_contestant
from .metrics import FIGURE_UNITS, FIGURES, measure
from .output import HEADLINE, text_summary, write_csv, write_plots, write_report
from .run import (CHECK_TOLERANCE_MM, ISSUE_41_FIGURES, BenchmarkResult, goals, reproduction_check, run_one,
                  run_suite)
from .suite import (CONTESTANT_TEXT, CONTESTANTS, NOT_RUN_CONTESTANTS, PLATE_NAMES, Plate, RunSpec,
                    SuiteParams, Zone, plates, runs, scenario_dict)

__all__ = ["PID_GAINS", "PROCESS_FUNCTIONS", "Track", "run_contestant", "FIGURE_UNITS", "FIGURES", "measure",
           "HEADLINE", "text_summary", "write_csv", "write_plots", "write_report", "CHECK_TOLERANCE_MM",
           "ISSUE_41_FIGURES", "BenchmarkResult", "goals", "reproduction_check", "run_one", "run_suite",
           "CONTESTANT_TEXT", "CONTESTANTS", "NOT_RUN_CONTESTANTS", "PLATE_NAMES", "Plate", "RunSpec",
           "SuiteParams", "Zone", "plates", "runs", "scenario_dict"]
