"""Running the step experiment: :func:`run_steps` (every setting on the same machine and step, measured)
and :func:`auto_step` (the default step that keeps every setting inside the slope limiter).

Part of :mod:`distctrl.workbench.step` (docs/workbench-step.md); the package face re-exports every name.
"""
from __future__ import annotations

import math
import os
import sys
from typing import Any, Iterable

from ...control.controller import AxisDistanceController
from ...params.listfile import parse_list_text
from ...sim.runner import run
from ...sim.scenario import Scenario, load_scenario
from .metrics import _offset_column, measure
from .model import (AUTO_MARGIN, AUTO_MAX_MM, AUTO_NOISE_FLOOR, DEFAULT_AXIS_LIST, DEFAULT_SENSOR, StepError,
                    StepSetting, StepSettingError, _round_down, _round_up, _sensor_dict, _step_axis, step_scenario)
from .result import StepResult


class _Bar:
    """A rich progress bar over the settings, on a terminal only."""

    def __init__(self, total: int, enabled: bool | None):
        self.bar = None
        if enabled is None:
            enabled = sys.stderr.isatty()
        if enabled and total > 0:
            # rich (0.1 s of import): only where a table or progress bar is printed
            from rich.console import Console
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

            self.bar = Progress(TextColumn("step responses"), BarColumn(), MofNCompleteColumn(),
                                TextColumn("{task.fields[label]}"), TimeElapsedColumn(), transient=True,
                                console=Console(stderr=True))
            self.bar.start()
            self.task = self.bar.add_task("step", total=total, label="")

    def update(self, done: int, label: str) -> None:
        if self.bar is not None:
            self.bar.update(self.task, completed=done, label=label)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.stop()


def _limits(params, setting: StepSetting, cycle_time: float) -> dict[str, float]:
    """The limiter's reach for ``setting`` on an axis with ``params`` (mm, s): ``v_max`` (P-AXIS-00415),
    ``a_max`` (P-AXIS-00416, or the axis acceleration when 0; a_min with adaptive acceleration, the
    lowering weights applied when smaller) and ``linear_step_mm``: the largest step whose first cycle
    the PID answers inside them (the wanted step ``k·step`` with ``k = KP (1 + T/T_n) + g_D`` within
    ``v_max·T``, ``a_max·T²`` and the braking bound ``sqrt(2 a_max e)``)."""
    ctrl = AxisDistanceController(params.replace(kp=setting.kp, i_tn=setting.i_tn, d_tv=setting.d_tv),
                                  cycle_time)
    c = ctrl.law_constants()
    T = float(c["T"])
    v = float(c["v_max"]) * min(1.0, float(c["w_v"]))
    a = float(c["a_base"]) * min(1.0, float(c["w_a"]))
    if params.use_adaptive_acceleration:
        a = min(a, float(params.a_min)) if params.a_min > 0 else a
    k = setting.kp * (1.0 + float(c["i_gain"])) + float(c["d_gain"])
    linear = min(v * T / k, a * T * T / k, 2.0 * a * T * T / (k * k)) if k > 0 and a > 0 and v > 0 else math.inf
    return {"v_max": v, "a_max": a, "linear_step_mm": linear}


def _axis_data(base: "Scenario | None") -> tuple[Any, float, dict[str, Any]]:
    """(parameter list, cycle time, sensor dict) of the axis a step runs on."""
    if base is None:
        return (parse_list_text(DEFAULT_AXIS_LIST, "<distctrl step default Z axis>").params, 0.001,
                dict(DEFAULT_SENSOR, axis="Z"))
    axis = _step_axis(base)
    return base.axes[axis].params, base.cycle_time, _sensor_dict(base, axis)


def auto_step(settings: Iterable[StepSetting], base: "Scenario | str | os.PathLike | None" = None
              ) -> tuple[float, str]:
    """The default step of ``distctrl step`` (``--step auto``): ``(step_mm, reason)``.

    The largest step that keeps the first cycle of every setting within :data:`AUTO_MARGIN` of the
    limiter's reach (:func:`_limits`: P-AXIS-00415 v_max, P-AXIS-00416 a_max), at most
    :data:`AUTO_MAX_MM`, rounded down to 2 significant digits; but not smaller than
    :data:`AUTO_NOISE_FLOOR` times the sensor's noise (a step drowned in noise measures the noise).
    When the noise floor wins, the limiter may still decide the largest KPs; :func:`measure` says so.
    """

    settings = list(settings)
    if not settings:
        raise StepSettingError("no settings; allowed: at least one StepSetting (see parse_settings)")
    if base is not None and not isinstance(base, Scenario):
        base = load_scenario(base)
    params, T, sensor = _axis_data(base)
    linear = min(_limits(params, s, T)["linear_step_mm"] for s in settings)
    want = min(AUTO_MAX_MM, AUTO_MARGIN * linear)
    want = _round_down(want)
    floor = _round_up(AUTO_NOISE_FLOOR * float(sensor.get("noise_std") or 0.0))
    if floor > want:
        return floor, (f"auto: {AUTO_NOISE_FLOOR:g} x the sensor noise ({sensor.get('noise_std'):g} mm); "
                       f"{want:g} mm would keep every setting inside P-AXIS-00415/00416")
    if want >= AUTO_MAX_MM:
        return want, "auto: every setting stays inside P-AXIS-00415/00416"
    return want, "auto: the largest KP's first cycle stays inside P-AXIS-00415/00416"



def run_steps(settings: Iterable[StepSetting], base: "Scenario | str | os.PathLike | None" = None, *,
              step_mm: "float | str" = 1.0, mode: str = "CONST_DIST", t_step: float = 0.5, duration: float = 2.0,
              set_dist: float = 1.0, ramp_mm_s: float = 0.0,
              progress: bool | None = None) -> list[StepResult]:
    """Run the step response of every setting (same machine, same step) and measure it.

    ``step_mm="auto"``: the step of :func:`auto_step`. All scenarios are built (and validated) before
    the first run, so bad input fails at once. ``progress``: a rich progress bar on stderr; ``None``
    (default) shows it when stderr is a terminal. ``trace.meta["step"]`` also holds the limiter's
    reach for the setting (``v_max``, ``a_max``, ``linear_step_mm``, see :func:`_limits`) and, with
    ``auto``, the reason for the step (``auto``).
    """

    settings = list(settings)
    if not settings:
        raise StepSettingError("no settings; allowed: at least one StepSetting (see parse_settings)")
    if base is not None and not isinstance(base, Scenario):
        base = load_scenario(base)
    auto = None
    if isinstance(step_mm, str):
        if step_mm.strip().lower() != "auto":
            raise StepError(f"step = {step_mm!r}; allowed: a step != 0 in mm, or 'auto'")
        step_mm, auto = auto_step(settings, base)
    scenarios = [step_scenario(base, s, step_mm, mode, t_step, duration, set_dist=set_dist,
                               ramp_mm_s=ramp_mm_s) for s in settings]
    params, T, _ = _axis_data(base)
    out: list[StepResult] = []
    bar = _Bar(len(settings), progress)
    try:
        for n, (setting, sc) in enumerate(zip(settings, scenarios)):
            bar.update(n, setting.label)
            res = run(sc)
            trace = res.trace
            col = _offset_column(trace, None)
            info = {"t_step": float(t_step), "step_mm": float(step_mm), "ramp_mm_s": float(ramp_mm_s),
                    "mode": mode.upper(), "column": col, "setting": setting.label, **_limits(params, setting, T)}
            if auto is not None:
                info["auto"] = auto
            trace.meta.update({"step": info, "errors": list(res.errors), "warnings": list(res.warnings)})
            out.append(StepResult(setting, measure(trace, t_step, step_mm, ramp_mm_s=ramp_mm_s, column=col),
                                  trace))
        bar.update(len(settings), "")
    finally:
        bar.close()
    return out
