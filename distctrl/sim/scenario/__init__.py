"""Scenarios: one simulated run described in a TOML file, loaded into typed, validated dataclasses.

A scenario names the NC program, the axes (with their kernel parameter lists and drive data), the
surface, the sensor, timed events (PLC commands, overrides, faults, ...) and the cycle time.
docs/scenarios.md documents every key. Paths inside a scenario are relative to the scenario file
(for :func:`scenario_from_dict` / :func:`scenario_from_text`: to ``base_dir``).

Every key is validated. A problem raises :class:`ScenarioError` (a
:class:`~distctrl.errors.config.ConfigError`) whose message names the file, the key path
(``axes.Z.kv``, ``events[2].plc.transition``), the value and what is allowed; unknown keys are
errors that list the allowed keys. Errors in a parameter list are
:class:`~distctrl.errors.ParameterError` with the list's own ``file:line`` (the scenario key is
appended to the message). Both derive from :class:`~distctrl.errors.DistCtrlError`.

Example::

    sc = load_scenario("examples/laser.toml")
    sc.axes["Z"].params.kp, sc.sensor.kind, [e.kind for e in sc.events]
    sensor = sc.make_sensor()            # EncoderProbe / DistanceSensor as configured
    drive = sc.axes["Z"].make_drive(sc.cycle_time)

The loader is one module per section, each with its keys, its result type and its reader:
``common`` (:class:`ScenarioError`, the small validators), ``axes`` (``[axes.X]``, :class:`AxisConfig`),
``sensor`` (``[sensor]``, :class:`SensorConfig`), ``channel`` (``[channel]``), ``events``
(``[[events]]``, :class:`Event`) and ``load`` (the top-level keys, :class:`Scenario` and the entry
points). ``[surface]`` is read by :func:`distctrl.sim.surface.surface_from_config`, ``[[process]]`` by
:func:`distctrl.plc.process.process_configs`. Every name is importable from here.
"""
from __future__ import annotations

from .axes import AXIS_KEYS, AXIS_NAMES, AxisConfig
from .channel import CA_AXES, CHANNEL_KEYS, KINEMATICS
from .common import ScenarioError
from .events import EVENT_KINDS, OVERRIDE_AXIS_MAX, OVERRIDE_PATH_MAX, Event
from .load import (CYCLE_TIME_MAX, CYCLE_TIME_MIN, TOP_LEVEL_KEYS, Scenario, load_scenario, scenario_from_dict,
                   scenario_from_text)
from .sensor import (ARC_CUT_SPEED_MAX, ARC_RIPPLE_MAX, ARC_SPEED_VOLTS_MAX, BURST_KEYS, FOOTPRINT_RADIUS_MAX,
                     KERF_JUMP_MAX, SENSOR_KEYS, SENSOR_KINDS, SENSOR_MODES, SensorConfig)

__all__ = ["Scenario", "AxisConfig", "SensorConfig", "Event", "ScenarioError", "load_scenario",
           "scenario_from_dict", "scenario_from_text", "AXIS_NAMES", "EVENT_KINDS", "TOP_LEVEL_KEYS",
           "AXIS_KEYS", "SENSOR_KEYS", "SENSOR_KINDS", "SENSOR_MODES", "CHANNEL_KEYS", "KINEMATICS"]
#: public constants importable from here besides ``__all__`` (as from the single module before)
_ALSO = (CA_AXES, OVERRIDE_AXIS_MAX, OVERRIDE_PATH_MAX, CYCLE_TIME_MAX, CYCLE_TIME_MIN, ARC_CUT_SPEED_MAX,
         ARC_RIPPLE_MAX, ARC_SPEED_VOLTS_MAX, BURST_KEYS, FOOTPRINT_RADIUS_MAX, KERF_JUMP_MAX)
