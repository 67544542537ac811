"""Parameter sweeps and auto-tuning on the closed-loop batch kernel (docs/tuning.md).

:mod:`~distctrl.tuning.space` (grids, random samples, validation), :mod:`~distctrl.tuning.metrics`
(vectorised quality figures), :mod:`~distctrl.tuning.runner` (chunked evaluation, local or on
dask.distributed) and :mod:`~distctrl.tuning.tune` (coarse sweep + refinement + robustness); the
click commands ``sweep`` and ``tune`` are in :mod:`distctrl.cli.tune`.
"""
from .metrics import METRIC_NAMES, compute_metrics, cost
from .runner import Evaluator, SweepResult, evaluate
from .space import SpaceError, build_sets, grid_points, parse_grid, random_sample, to_params

__all__ = ["METRIC_NAMES", "compute_metrics", "cost", "Evaluator", "SweepResult", "evaluate", "SpaceError",
           "build_sets", "grid_points", "parse_grid", "random_sample", "to_params"]
