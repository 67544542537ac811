"""The loop of a scenario: :func:`loop_model` runs it until distance control is first selected and
builds the :class:`LoopModel` of the tuning in force then.

Part of :mod:`distctrl.workbench.margins` (docs/margins.md); the package face re-exports every name.
"""
from __future__ import annotations

import dataclasses
import math
import os

import numpy as np

from ...base.kinds import SensorSource
from ...base.states import HliState, Mode
from ...sim.machine import Machine
from ...sim.runner import load_program
from ...sim.scenario import Scenario, load_scenario
from .model import KP_RANGE, SELECT_SEARCH_S, LoopModel, MarginsError, model_from_parts


def _pick_axis(sc: "Scenario", axis: str | None) -> str:
    dc = [n for n, a in sc.axes.items() if a.params.enabled]
    if axis is not None:
        if axis not in sc.axes:
            raise MarginsError(f"scenario {sc.name!r}: no axis {axis!r}; allowed: one of {', '.join(sc.axes)}")
        if axis not in dc:
            raise MarginsError(f"scenario {sc.name!r}: axis {axis} has no distance control "
                               f"(lr_param.distance_control_on = 0); allowed: {', '.join(dc) or 'none'}")
        return axis
    sensor_axis = sc.sensor.axis if sc.sensor is not None else None
    if sensor_axis in dc:
        return sensor_axis
    if len(dc) == 1:
        return dc[0]
    if not dc:
        raise MarginsError(f"scenario {sc.name!r}: no axis with distance control (P-AXIS-00328 = 1 in a "
                           f"parameter list); allowed: a scenario with a distance-controlled axis")
    raise MarginsError(f"scenario {sc.name!r}: several distance-controlled axes ({', '.join(dc)}); "
                       f"name one with --axis")


def _sensor_gain(sc: "Scenario", distance: float) -> tuple[float, str | None]:
    """The slope of the distance sensor's characteristic at ``distance`` (reported mm), 1 without one."""
    s = sc.sensor
    if s is None or s.kind != "distance" or s.characteristic is None:
        return 1.0, None
    xs = np.array([p[0] for p in s.characteristic])
    ys = np.array([p[1] for p in s.characteristic])
    slopes = np.diff(ys) / np.diff(xs)
    # the segment in which the reported value equals the operating distance (first one found)
    for i, (y0, y1) in enumerate(zip(ys[:-1], ys[1:])):
        if min(y0, y1) <= distance <= max(y0, y1) and slopes[i] != 0.0:
            return float(slopes[i]), (f"sensor characteristic: slope {slopes[i]:.4g} mm/mm at the reported "
                                      f"distance {distance:g} mm")
    return 0.0, (f"sensor characteristic: the reported distance {distance:g} mm is outside the table or on "
                 f"a flat part; slope 0 mm/mm (the loop is open)")


def loop_model(scenario: "Scenario | str | os.PathLike", axis: str | None = None, kp: float | None = None,
               ) -> LoopModel:
    """The linearised loop of ``axis`` (default: the sensor's axis) of a scenario.

    The machine runs the scenario until the program (or a PLC event) first selects distance control on
    the axis, so the mode (CONST_DIST / SET_POS) and the tuning are the ones in force then (KP, I_TN,
    D_TV and the filter of the NC block or the list). A program that never selects it within the
    scenario's duration (at most 60 s) is modelled with the list's values in CONST_DIST, with a note.
    ``kp`` overrides KP (0 < KP <= 2). 3D (channel) distance control is not supported.
    """
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    if sc.has_3d or (sc.sensor is not None and sc.sensor.orthogonal):
        raise MarginsError(f"scenario {sc.name!r}: 3D (channel) distance control is not supported by "
                           f"distctrl margins; allowed: a scenario with axis-specific distance control "
                           f"(the axis variant, FCT-M3 ch. 2-11)")
    name = _pick_axis(sc, axis)
    if kp is not None:
        if isinstance(kp, bool) or not isinstance(kp, (int, float)) or not math.isfinite(kp) \
                or not KP_RANGE[0] < kp <= KP_RANGE[1]:
            raise MarginsError(f"KP = {kp!r} is out of range; allowed: {KP_RANGE[0]:g} < KP <= {KP_RANGE[1]:g} "
                               f"(P-AXIS-00759)")
    if sc.sensor is None or sc.sensor.axis != name:
        what = "no [sensor]" if sc.sensor is None else f"the sensor measures axis {sc.sensor.axis}"
        raise MarginsError(f"scenario {sc.name!r}: {what}, so nothing closes the loop of axis {name}; allowed: "
                           f"a scenario whose [sensor] axis is {name}")
    ax = sc.axes[name]
    notes: list[str] = []
    machine = Machine(sc, load_program(sc))
    ctrl = machine.controllers[name]
    limit = SELECT_SEARCH_S if sc.duration is None else min(sc.duration, SELECT_SEARCH_S)
    tracking = (HliState.ACTIVE, HliState.ACTIVE_CONST_DIST)
    selected = False
    for _ in range(int(round(limit / sc.cycle_time))):
        machine.step()
        if ctrl.state.hli_state in tracking:
            selected = True
            break
    if selected:
        mode = "CONST_DIST" if ctrl.state.mode == Mode.CONST_DIST else "SET_POS"
        tuning = ctrl.tuning
        source = f"in force at the first select (t = {machine.cycle * sc.cycle_time:.3f} s)"
        distance = ctrl.state.set_dist if mode == "CONST_DIST" else machine.outputs[name].measured_distance
        if sc.sensor.kind == "distance" and ctrl.state.sensor_source != SensorSource.VARIABLE:
            notes.append(f"the sensor writes V.E.{sc.sensor.variable} but {name} reads encoder 2 (no "
                         f"SENSOR_SOURCE=VARIABLE): in the simulator the loop is open; the model assumes it is read")
    else:
        mode, tuning, distance = "CONST_DIST", None, 0.0
        source = "parameter list"
        notes.append(f"the program does not select distance control on {name} within {limit:g} s: the "
                     f"parameter list's KP, I_TN, D_TV and filter, CONST_DIST assumed")
    gain, note = _sensor_gain(sc, distance)
    if note:
        notes.append(note)
    model = model_from_parts(ax.params, sc.cycle_time, axis=name, mode=mode, kv=ax.kv, feedforward=ax.feedforward,
                             bus_delay_cycles=ax.bus_delay_cycles,
                             sensor_delay_cycles=sc.sensor.delay_cycles if sc.sensor is not None else 0,
                             sensor_gain=gain, scenario=str(sc.path or sc.name), kp_source=source,
                             tuning=tuning, notes=tuple(notes), resonance_hz=ax.resonance_hz, damping=ax.damping)
    if kp is not None:
        model = dataclasses.replace(model.with_kp(kp), kp_source="--kp")
    return model
