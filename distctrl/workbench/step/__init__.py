"""Step-response workbench: the documents' controller-tuning method on the virtual machine.

FCT-M3 ch. 3 tunes distance control step by step: first a P controller (I and D off) starting at
``K_p = 0.2``; observe the response of the control loop to a *defined change in distance* and raise
``K_p`` until there is a recognisable but rapidly decaying oscillation; then the I part (start
``T_n = 5`` s, reduce it) only against a permanent control deviation; then the D part (start
``T_v = 0.01`` s) to damp oscillations. This package makes that experiment repeatable:

* :func:`parse_settings` turns ``--kp 0.2,0.5,1 --i-tn 0 --d-tv 0,0.01`` into the cartesian product
  of :class:`StepSetting`;
* :func:`step_scenario` builds the run: a Z axis with a probe (or the Z axis, parameter list and
  sensor of a given scenario) holding the set distance, and at ``t_step`` the sensor sees the
  surface rise by ``step_mm`` (a sensor ``jump`` fault, see below);
* :func:`measure` reads rise time, overshoot, settling time, steady-state error and the number of
  oscillation swings from the offset response ``<axis>.dc.offset``;
* :func:`run_steps`, :func:`format_table`, :func:`hints` and :func:`plot_steps` run a sweep and
  present it (``distctrl step``, docs/workbench-step.md).

Why a sensor ``jump`` and not a step in the surface: the jump happens exactly at ``t_step`` (a step
feature needs an X motion and is crossed when the interpolator gets there), and the controller
cannot tell the two apart -- it sees the same change of its measurement -- so the *offset* response
is the same. The difference is the true distance: a real surface step also changes the true
distance (it drops by the step and recovers as the offset lifts the axis), the fault does not (the
true distance *grows* by the step while the offset follows the fake reading). The metrics therefore
use the offset, never ``true.distance``.

Errors are :class:`StepError` (a ``DistCtrlError``) whose messages say what is allowed.

The modules, by role (this face re-exports every name, so ``from distctrl.workbench.step import ...``
works as before):

* ``model``: the documented ranges and constants, the errors, :class:`StepSetting` and the scenario;
* ``metrics``: :class:`StepMetrics`, :func:`measure` and the class of a response;
* ``result``: :class:`StepResult` (``to_dict``, ``plot``, ``to_csv``) and :func:`plot_steps`;
* ``sweep``: :func:`run_steps` and :func:`auto_step`;
* ``text``: :func:`format_table`, :func:`hints`, :func:`suggested_kp` and :func:`results_json`.
"""
from __future__ import annotations

from ..plotfiles import PLOT_SUFFIXES  # noqa: F401  (part of the API)
from .metrics import StepMetrics, _classify, _offset_column, measure  # noqa: F401
from .model import (AUTO_MARGIN, AUTO_MAX_MM, AUTO_NOISE_FLOOR, BAND, D_TV_RANGE, DEFAULT_AXIS,  # noqa: F401
                    DEFAULT_AXIS_LIST, DEFAULT_SENSOR, I_TN_RANGE, KP_RANGE, LARGE_PCT, LIMITED_SHARE,
                    MAX_DURATION, MODES, NOISE_SIGMAS, RAPID_CROSSINGS, RECOGNISABLE_PCT, StepError, StepSetting,
                    StepSettingError, parse_settings, step_scenario)
from .result import MIN_VIEW_S, SETTLE_VIEW, StepResult, check_plot_path, plot_steps  # noqa: F401
from .sweep import auto_step, run_steps  # noqa: F401
from .text import D_NO_EFFECT_KP, LIMITER_IDS, TABLE_COLUMNS, format_table, hints, results_json, suggested_kp  # noqa: F401

__all__ = [
    "StepError", "StepSettingError", "StepSetting", "StepMetrics", "StepResult",
    "KP_RANGE", "I_TN_RANGE", "D_TV_RANGE", "MODES", "BAND", "RECOGNISABLE_PCT", "RAPID_CROSSINGS",
    "LARGE_PCT", "DEFAULT_AXIS_LIST", "DEFAULT_AXIS", "DEFAULT_SENSOR", "parse_settings", "step_scenario",
    "measure", "run_steps", "format_table", "hints", "plot_steps", "check_plot_path", "auto_step",
    "suggested_kp", "LIMITED_SHARE", "NOISE_SIGMAS", "results_json",
]
