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
"""
from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

from distctrl.base.states import HliTransition
from distctrl.errors import ParameterError
from distctrl.params.axis import AxisParameters
from distctrl.params.channel import ChannelParameters, load_channel_list
from distctrl.params.external_variables import load_external_variables
from distctrl.params.listfile import load_list
from distctrl.errors.config import (MAX_DELAY_CYCLES, MISSING, ConfigError, require_choice, require_int,
                                        require_mapping, require_number)
from distctrl.sim.drive import Drive
from distctrl.sim.interpolator import AxisLimits
from distctrl.sim.sensors import (FAULT_KINDS, FOOTPRINT_POINTS, ArcVoltageSensor, Bursts, DistanceSensor,
                                   EncoderProbe, Fault, SensorBase)
from distctrl.sim.surface import Surface, surface_from_config

__all__ = ["Scenario", "AxisConfig", "SensorConfig", "Event", "ScenarioError", "load_scenario",
           "scenario_from_dict", "scenario_from_text", "AXIS_NAMES", "EVENT_KINDS", "TOP_LEVEL_KEYS",
           "AXIS_KEYS", "SENSOR_KEYS", "SENSOR_KINDS", "SENSOR_MODES", "CHANNEL_KEYS", "KINEMATICS"]

#: axis names a scenario may configure (the order is the display order)
AXIS_NAMES = ("X", "Y", "Z", "A", "B", "C")
TOP_LEVEL_KEYS = ("name", "cycle_time", "program", "program_text", "duration", "settle_time", "seed",
                  "variables", "external_variables", "tool", "axes", "channel", "surface", "sensor", "events",
                  "process")                      # issue 16: [[process]] tables (docs/process.md)
AXIS_KEYS = ("params", "start", "kv", "v_max", "a_max", "v_rapid", "a_rapid", "bus_delay_cycles",
             "resolution", "feedforward",
             "resonance_hz", "damping")           # the drive's mechanical resonance (issue 15)
SENSOR_KINDS = ("encoder", "distance", "arc_voltage")
#: what the sensor measures: "axis" - the height of the sensor axis above the surface (vertical, the
#: axis variant); "orthogonal_clamping_point" - the orthogonal distance of the tool clamping point
#: from the surface (3D distance control, FCT-M3 §12.3)
SENSOR_MODES = ("axis", "orthogonal_clamping_point")
SENSOR_KEYS = ("axis", "kind", "mode", "variable", "noise_std", "delay_cycles", "seed", "range_min", "reading_at_contact",
               "range_max", "characteristic", "resolution", "faults", "collision_depth",
               # issue 15: capacitive edge effect and bursts, plasma arc voltage (docs/scenarios.md)
               "footprint_radius", "footprint_points", "field_range", "bursts", "voltage_variable", "arc_v0", "arc_k", "arc_ripple",
               "arc_ripple_hz", "arc_noise_std", "kerf_jump", "plc_v0", "plc_k",
               # issue 16: the arc voltage's rise when the torch slows (docs/sim-models.md)
               "arc_speed_volts", "arc_cut_speed", "arc_speed_tau",
               # issue 16: the PLC's linearisation table of a distance sensor (distctrl calibrate)
               "linearisation", "raw_variable")
#: sensor keys that only some kinds accept
_SENSOR_KIND_ONLY = {"variable": ("distance", "arc_voltage"), "characteristic": ("distance",),
                     "resolution": ("distance",), "range_min": ("encoder",), "reading_at_contact": ("encoder",),
                     "footprint_radius": ("distance", "arc_voltage"), "field_range": ("distance", "arc_voltage"),
                     "footprint_points": ("distance", "arc_voltage"),
                     "bursts": ("distance", "arc_voltage"),
                     "linearisation": ("distance",), "raw_variable": ("distance",),
                     **{k: ("arc_voltage",) for k in ("voltage_variable", "arc_v0", "arc_k", "arc_ripple",
                                                      "arc_ripple_hz", "arc_noise_std", "kerf_jump", "plc_v0",
                                                      "plc_k", "arc_speed_volts", "arc_cut_speed",
                                                      "arc_speed_tau")}}
#: the keys of ``sensor.bursts`` (required: rate, duration, amplitude)
BURST_KEYS = ("rate", "duration", "amplitude", "offset")
#: largest footprint radius (mm): a nozzle's electrode or a torch's arc root is a few mm
FOOTPRINT_RADIUS_MAX = 25.0
#: largest arc ripple, arc noise (V) and kerf jump (V) a scenario may give
ARC_RIPPLE_MAX = 50.0
KERF_JUMP_MAX = 500.0
#: largest slow-down rise (V) and cut speed (mm/s, 60 m/min) of the arc voltage's slow-down model
ARC_SPEED_VOLTS_MAX = 100.0
ARC_CUT_SPEED_MAX = 1000.0
#: [channel]: the kernel channel list (3D distance control) and the head kinematics
CHANNEL_KEYS = ("params", "kinematics")
#: head kinematics a channel may have: "CA" (5-axis CA head, kinematic ID 9) or "none"
KINEMATICS = ("CA", "none")
#: the axes the CA head needs
CA_AXES = ("X", "Y", "Z", "A", "C")
#: event action -> (allowed keys, required keys)
EVENT_KINDS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "plc": (("axis", "transition", "position"), ("axis", "transition")),
    "override": (("axis", "value"), ("value",)),
    "feed_hold": (("axis", "value"), ("axis",)),
    "reset": ((), ()),
    "axis_error": (("axis",), ("axis",)),
    "axis_release": (("axis",), ("axis",)),
    "sensor_fault": (("kind", "value", "duration", "duration_cycles", "rate"), ("kind",)),
    "variable": (("name", "value"), ("name", "value")),
    "plc_cyclic": (("axis", "position", "distance"), ("axis",)),
    "start": (("program", "program_text"), ()),
}
_FAULT_KEYS = ("kind", "start_time", "start_cycle", "duration", "duration_cycles", "value", "rate")

CYCLE_TIME_MIN, CYCLE_TIME_MAX = 1e-4, 0.1
OVERRIDE_AXIS_MAX = 1.0
OVERRIDE_PATH_MAX = 1.27
_NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_TOML_LINE_RE = re.compile(r"at line (\d+)")


# --- errors ------------------------------------------------------------------------------------------
class ScenarioError(ConfigError):
    """A :class:`ConfigError` in a scenario: the message starts with the file (and line if known).

    ``key`` stays the bare key path (``axes.Z.kv``); ``file`` and ``line`` hold the location.
    """

    def __init__(self, file: str, key: str, value: object, allowed: str, problem: str = "invalid value",
                 line: int | None = None):
        super().__init__(key, value, allowed, problem)
        self.file = file
        self.line = line
        where = file if line is None else f"{file}:{line}"
        self.args = (f"{where}: {self.args[0]}",)

    def rekeyed(self, key: str) -> "ScenarioError":
        return ScenarioError(self.file, key, self.value, self.allowed, self.problem, self.line)


def _rekey(exc: ConfigError, prefix: str, path: str) -> ConfigError:
    """``Fault.value`` -> ``events[3].sensor_fault.value`` (other keys: under ``path``)."""
    key = exc.key
    if key.startswith(prefix + "."):
        return exc.rekeyed(path + key[len(prefix):])
    return exc.rekeyed(f"{path} ({key})")


# --- result types ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class AxisConfig:
    """One axis: its distance-control parameter list plus drive and interpolation data (mm, s)."""

    name: str
    params: AxisParameters
    params_file: Path | None
    start: float = 0.0                 # mm
    kv: float = 40.0                   # 1/s
    v_max: float = 500.0               # mm/s
    a_max: float = 10000.0             # mm/s^2
    v_rapid: float = 500.0             # mm/s
    a_rapid: float = 10000.0           # mm/s^2
    bus_delay_cycles: int = 1
    resolution: float = 1e-4           # mm per motor encoder increment
    params_warnings: tuple[str, ...] = ()  # warnings of the list loader (a key given twice, ...)
    feedforward: float = 0.0           # drive velocity feed-forward 0..1
    # -- the drive's mechanical resonance between motor and nozzle (docs/sim-models.md "Drive")
    resonance_hz: float = 0.0          # f0, Hz; 0 = rigid drive
    damping: float = 0.05              # zeta, 0 < zeta <= 1

    def limits(self) -> AxisLimits:
        """The interpolator's limits of this axis."""
        return AxisLimits(self.v_max, self.a_max, self.v_rapid, self.a_rapid)

    def make_drive(self, cycle_time: float) -> Drive:
        """A :class:`Drive` at rest at ``start``."""
        return Drive(cycle_time, kv=self.kv, v_max=self.v_max, a_max=self.a_max,
                     bus_delay_cycles=self.bus_delay_cycles, resolution=self.resolution,
                     initial_position=self.start, velocity_feedforward=self.feedforward,
                     resonance_hz=self.resonance_hz, damping=self.damping)


@dataclass(frozen=True)
class SensorConfig:
    """The height sensor: ``kind`` "encoder" (encoder-2 probe, increments) or "distance" (V.E. variable).

    ``variable`` (distance sensor only, else ``None``) is the bare V.E. name, e.g. ``"SENSOR"``.
    ``range_min`` is ``None`` for the distance sensor (its range starts at 0). ``faults`` are the
    faults scheduled from ``sensor.faults`` (the ``sensor_fault`` events are separate).
    ``mode`` (:data:`SENSOR_MODES`): ``"axis"`` measures the sensor axis's height above the surface;
    ``"orthogonal_clamping_point"`` (distance sensor of a channel with 3D distance control) the
    orthogonal distance of the tool clamping point; ``axis`` is then optional (``None``) and unused.
    """

    axis: str | None
    kind: str
    variable: str | None = None
    noise_std: float = 0.0                 # mm
    delay_cycles: int = 0
    seed: int = 0
    range_min: float | None = -10.0        # mm
    range_max: float = 10.0                # mm
    characteristic: tuple[tuple[float, float], ...] | None = None
    resolution: float = 0.0                # mm (distance sensor quantisation, 0 = none)
    faults: tuple[Fault, ...] = ()
    mode: str = "axis"
    #: probe only: what encoder 2 reads (mm, after resolution and sign, before P-AXIS-00418) when the
    #: tool touches the surface -- the probe's own physical zero. The list's ref_offset (P-AXIS-00418)
    #: must be its negative for the core to read the true distance (a wrong one shows as a wrong distance)
    reading_at_contact: float = 0.0
    #: how far the tool may be below the surface before the run records a collision (mm, >= 0): 0 for a
    #: nozzle that must never touch the sheet; a tactile probe's stroke for a probe that rides on it
    collision_depth: float = 0.0
    # --- issue 15: capacitive edge effect, bursts, plasma arc voltage (docs/sim-models.md) ---
    #: distance / arc voltage: radius of the footprint (mm; 0 = the point under the tool)
    footprint_radius: float = 0.0
    #: distance / arc voltage: sample points of the footprint (8, 16, 24 or 32)
    footprint_points: int = 16
    #: distance / arc voltage: sheet farther than this from the sensor is "no sheet" (mm; None = range_max)
    field_range: float | None = None
    #: distance / arc voltage: plume/spark noise bursts (None = none)
    bursts: Bursts | None = None
    #: arc voltage: the V.E. variable the arc voltage (V) is written to (bare name)
    voltage_variable: str | None = None
    arc_v0: float = 100.0                  # V at zero arc length
    arc_k: float = 6.0                     # V/mm
    arc_ripple: float = 0.0                # V amplitude of the mains ripple
    arc_ripple_hz: float = 50.0            # Hz
    arc_noise_std: float = 0.0             # V white noise
    kerf_jump: float = 0.0                 # V with no sheet under the whole footprint
    arc_speed_volts: float = 0.0           # V rise at rest in a cut (0: no slow-down model)
    arc_cut_speed: float | None = None     # mm/s: the speed at which the rise is 0
    arc_speed_tau: float = 0.02            # s: the rise's lag behind the speed
    #: arc voltage: the PLC linearisation's V0 (V) and k (V/mm); None = the arc's own (calibrated)
    plc_v0: float | None = None
    plc_k: float | None = None
    # --- issue 16: the PLC linearises a distance sensor's reading through a table (distctrl calibrate) ---
    #: distance: (reading mm, distance mm) pairs the PLC interpolates (None = the sensor writes ``variable``)
    linearisation: tuple[tuple[float, float], ...] | None = None
    #: distance with a linearisation: the V.E. variable the sensor writes its reading to (bare name)
    raw_variable: str | None = None
    #: the TOML file the table came from (``linearisation = "table.toml"``), else None
    linearisation_file: Path | None = None

    @property
    def output_variable(self) -> str | None:
        """The bare V.E. name the sensor writes: the voltage variable of an arc-voltage sensor, the
        distance variable of a distance sensor, None for the probe (encoder 2)."""
        if self.kind == "arc_voltage":
            return self.voltage_variable
        return self.raw_variable if self.linearisation is not None else self.variable

    def make_plc_program(self):
        """The PLC program the sensor needs (the arc voltage's linearisation,
        :class:`distctrl.plc.arc_voltage.ArcVoltageLinearisation`; a distance sensor's table,
        :class:`distctrl.plc.linearisation.DistanceLinearisation`), or None."""
        if self.kind == "distance" and self.linearisation is not None:
            from distctrl.plc.linearisation import DistanceLinearisation
            return DistanceLinearisation(self.linearisation, f"V.E.{self.raw_variable}", f"V.E.{self.variable}")
        if self.kind != "arc_voltage":
            return None
        from distctrl.plc.arc_voltage import ArcVoltageLinearisation
        return ArcVoltageLinearisation(self.arc_v0 if self.plc_v0 is None else self.plc_v0,
                                       self.arc_k if self.plc_k is None else self.plc_k,
                                       f"V.E.{self.voltage_variable}", f"V.E.{self.variable}")

    @property
    def orthogonal(self) -> bool:
        """The sensor reports the orthogonal distance of the tool clamping point (3D)."""
        return self.mode == "orthogonal_clamping_point"

    def make_sensor(self, cycle_time: float, params: AxisParameters | None = None,
                    surface: Surface | None = None) -> SensorBase:
        """Build the sensor model. The probe takes its resolution and sign reversal from the axis
        parameters (P-AXIS-00422/00423/00230), so the core's conversion inverts them; its zero is its
        own (``reading_at_contact``), so the core reads the true distance only with the matching
        P-AXIS-00418 ref_offset = -reading_at_contact. A footprint (``footprint_radius > 0``) samples
        ``surface`` (the scenario's)."""
        common = dict(noise_std=self.noise_std, delay_cycles=self.delay_cycles, seed=self.seed,
                      faults=self.faults)
        if self.kind == "encoder":
            p = params or AxisParameters()
            return EncoderProbe(cycle_time, range_min=self.range_min, range_max=self.range_max,
                                resolution_num=p.encoder_resolution_num,
                                resolution_denom=p.encoder_resolution_denom,
                                sign_reversal=p.sensor_sign_reversal, ref_offset=-self.reading_at_contact,
                                **common)
        extra = dict(footprint_radius=self.footprint_radius, field_range=self.field_range, surface=surface,
                     bursts=self.bursts, footprint_points=self.footprint_points)
        if self.kind == "arc_voltage":
            return ArcVoltageSensor(cycle_time, v0=self.arc_v0, k=self.arc_k, ripple=self.arc_ripple,
                                    ripple_hz=self.arc_ripple_hz, voltage_noise_std=self.arc_noise_std,
                                    kerf_jump=self.kerf_jump, range_max=self.range_max,
                                    speed_volts=self.arc_speed_volts, cut_speed=self.arc_cut_speed,
                                    speed_tau=self.arc_speed_tau, **common, **extra)
        return DistanceSensor(cycle_time, range_max=self.range_max, characteristic=self.characteristic,
                              resolution=self.resolution, **common, **extra)


@dataclass(frozen=True)
class Event:
    """A timed action at ``t`` seconds. ``kind`` is one of :data:`EVENT_KINDS`; ``data`` holds the
    normalised values (see docs/scenarios.md); ``index`` is the event's position in the file."""

    t: float
    kind: str
    data: dict = field(default_factory=dict)
    index: int = 0


@dataclass(frozen=True)
class Scenario:
    """A validated scenario. ``events`` are sorted by ``t`` (stable: equal times keep file order)."""

    path: Path | None
    base_dir: Path
    name: str
    cycle_time: float
    program_text: str
    program_file: Path | None
    duration: float | None
    settle_time: float
    seed: int
    variables: dict[str, float]
    tool_length: float
    axes: dict[str, AxisConfig]
    surface: Surface
    surface_config: dict
    sensor: SensorConfig | None
    events: list[Event]
    #: ``[channel] params``: the channel's 3D distance-control parameters (None: no channel list)
    channel_params: ChannelParameters | None = None
    channel_params_file: Path | None = None
    channel_params_warnings: tuple[str, ...] = ()
    #: ``[channel] kinematics``: "CA" (the 5-axis CA head) or None
    kinematics: str | None = None
    #: ``external_variables``: the V.E. variables declared by the external-variable list (FCT-M3
    #: §12.8.4), None without a list (then every V.E. name a scenario or program uses exists)
    external_variables: dict | None = None
    external_variables_file: Path | None = None
    # --- issue 16: the [[process]] tables (docs/process.md) ---
    #: the cutting-process functions (:class:`distctrl.plc.process.ProcessConfig`), in file order
    processes: tuple = ()

    def make_process_program(self):
        """The ``[[process]]`` functions as one PLC program
        (:class:`distctrl.plc.process.ProcessProgram`), or None without any."""
        if not self.processes:
            return None
        from distctrl.plc.process import make_process_program
        return make_process_program(self.processes, self.cycle_time)

    @property
    def has_3d(self) -> bool:
        """The channel has 3D distance control (P-CHAN-00500 FCT_3D_DIST_CTRL in its list)."""
        return self.channel_params is not None and self.channel_params.fct_3d_dist_ctrl

    def make_sensor(self) -> SensorBase | None:
        """The configured sensor model (``None`` without ``[sensor]``)."""
        if self.sensor is None:
            return None
        axis = self.sensor.axis
        return self.sensor.make_sensor(self.cycle_time, self.axes[axis].params if axis is not None else None,
                                       self.surface)

    def make_drives(self) -> dict[str, Drive]:
        return {name: ax.make_drive(self.cycle_time) for name, ax in self.axes.items()}

    def axis_limits(self) -> dict[str, AxisLimits]:
        return {name: ax.limits() for name, ax in self.axes.items()}


# --- small validators ---------------------------------------------------------------------------------
def _string(value: object, key: str, what: str) -> str:
    if not isinstance(value, str) or not value:
        raise ConfigError(key, value, what, "not a non-empty string:" if not isinstance(value, str)
                          else "empty:")
    return value


def _var_name(value: object, key: str) -> str:
    """A V.E. variable name; an optional ``V.E.`` prefix is dropped."""
    allowed = "a V.E. variable name: letter or '_' then letters, digits, '_' (optional prefix 'V.E.')"
    if isinstance(value, str):
        name = value[4:] if value[:4].upper() == "V.E." else value
        if _NAME_RE.match(name):
            return name
    raise ConfigError(key, value, allowed)


def _bool(value: object, key: str) -> bool:
    if not isinstance(value, bool):
        raise ConfigError(key, value, "true or false", "not a boolean:")
    return value


def _axis_ref(value: object, key: str, axes: dict) -> str:
    if not isinstance(value, str) or value not in axes:
        raise ConfigError(key, value, "one of the configured axes " + ", ".join(repr(a) for a in axes))
    return value


def _file(value: object, key: str, base_dir: Path, what: str) -> Path:
    text = _string(value, key, f"a path to {what} (relative to {str(base_dir)!r})")
    path = Path(text)
    full = path if path.is_absolute() else base_dir / path
    try:
        found = full.is_file()
    except OSError as exc:          # e.g. a name too long for the OS (ENAMETOOLONG): no such file either
        raise ConfigError(key, text, f"an existing {what} (relative paths: to {str(base_dir)!r})",
                          f"file not readable ({exc.strerror}):") from None
    if not found:
        raise ConfigError(key, text, f"an existing {what} (relative paths: to {str(base_dir)!r})",
                          f"file not found ({full}):")
    return full


def _transition(value: object, key: str) -> int:
    names = [t.name for t in HliTransition]
    lo, hi = min(HliTransition), max(HliTransition)
    allowed = ("one of " + ", ".join(f"{t.name} ({int(t)})" for t in HliTransition)
               + f": a name or a number {int(lo)}..{int(hi)}")
    if isinstance(value, str):
        if value.upper() in names:
            return int(HliTransition[value.upper()])
        raise ConfigError(key, value, allowed, "unknown transition")
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value != value \
            or value in (math.inf, -math.inf) or int(value) != value:
        raise ConfigError(key, value, allowed)
    if not lo <= int(value) <= hi:
        raise ConfigError(key, value, allowed, "out of range:")
    return int(value)


# --- sections -----------------------------------------------------------------------------------------
def _axis_config(name: str, cfg: object, base_dir: Path, cycle_time: float) -> AxisConfig:
    key = f"axes.{name}"
    require_mapping(cfg, key, AXIS_KEYS)
    assert isinstance(cfg, dict)
    params, params_file, warnings = AxisParameters(), None, ()
    if "params" in cfg:
        params_file = _file(cfg["params"], f"{key}.params", base_dir, "axis parameter list (kernel format)")
        try:
            plist = load_list(params_file)
        except ParameterError as exc:
            exc.scenario_key = f"{key}.params"  # type: ignore[attr-defined]  # see _with_source
            raise
        params, warnings = plist.params, tuple(plist.warnings)
    start = require_number(cfg.get("start", 0.0), f"{key}.start")
    kv_max = 1.0 / cycle_time
    kv_value = cfg.get("kv", 40.0)
    kv_default = "" if "kv" in cfg else " (the default)"
    try:
        kv = require_number(kv_value, f"{key}.kv", lo=0.0, hi=kv_max, lo_open=True, hi_open=True)
    except ConfigError as exc:
        raise ConfigError(f"{key}.kv", kv_value,
                          f"a number in (0, {kv_max:g}) 1/s: kv * cycle_time < 1 "
                          f"(cycle_time = {cycle_time:g} s){kv_default}", exc.problem) from None
    v_max = require_number(cfg.get("v_max", 500.0), f"{key}.v_max", lo=0.0, lo_open=True)
    a_max = require_number(cfg.get("a_max", 10000.0), f"{key}.a_max", lo=0.0, lo_open=True)
    v_rapid = require_number(cfg.get("v_rapid", v_max), f"{key}.v_rapid", lo=0.0, lo_open=True)
    a_rapid = require_number(cfg.get("a_rapid", a_max), f"{key}.a_rapid", lo=0.0, lo_open=True)
    bus = require_int(cfg.get("bus_delay_cycles", 1), f"{key}.bus_delay_cycles", lo=0,
                      hi=MAX_DELAY_CYCLES)
    resolution = require_number(cfg.get("resolution", 1e-4), f"{key}.resolution", lo=0.0)
    feedforward = require_number(cfg.get("feedforward", 0.0), f"{key}.feedforward", lo=0.0, hi=1.0)
    resonance_hz, damping = _resonance(cfg, key, cycle_time)
    return AxisConfig(name, params, params_file, start, kv, v_max, a_max, v_rapid, a_rapid, bus, resolution,
                      warnings, feedforward, resonance_hz, damping)


def _resonance(cfg: dict, key: str, cycle_time: float) -> tuple[float, float]:
    """``resonance_hz`` (0 = rigid, else up to 1/(4 cycle_time)) and ``damping`` (0 < zeta <= 1)."""
    f_max = 0.25 / cycle_time
    value = cfg.get("resonance_hz", 0.0)
    try:
        f0 = require_number(value, f"{key}.resonance_hz", lo=0.0, hi=f_max)
    except ConfigError as exc:
        raise ConfigError(f"{key}.resonance_hz", value,
                          f"a number in [0, {f_max:g}] Hz: 0 (a rigid drive) or up to 1/(4 cycle_time) "
                          f"(cycle_time = {cycle_time:g} s)", exc.problem) from None
    value = cfg.get("damping", 0.05)
    try:
        zeta = require_number(value, f"{key}.damping", lo=0.0, hi=1.0, lo_open=True)
    except ConfigError as exc:
        raise ConfigError(f"{key}.damping", value, "a damping ratio in (0, 1]", exc.problem) from None
    return f0, zeta


def _fault(cfg: dict, key: str, *, start_time: float | None = None) -> Fault:
    args = dict(cfg)
    if start_time is not None:
        args["start_time"] = start_time
    if "kind" in args:
        require_choice(args["kind"], f"{key}.kind", FAULT_KINDS)
    try:
        return Fault(**args)
    except ConfigError as exc:
        raise _rekey(exc, "Fault", key) from None


def _sensor_config(cfg: object, axes: dict[str, AxisConfig], seed: int, cycle_time: float,
                   has_3d: bool = False, surface: Surface | None = None,
                   base_dir: Path = Path(".")) -> SensorConfig:
    key = "sensor"
    require_mapping(cfg, key, SENSOR_KEYS, required=("kind",))
    assert isinstance(cfg, dict)
    kind = require_choice(cfg["kind"], f"{key}.kind", SENSOR_KINDS)
    default_mode = "orthogonal_clamping_point" if has_3d and kind == "distance" else "axis"
    mode = require_choice(cfg.get("mode", default_mode), f"{key}.mode", SENSOR_MODES)
    if mode == "orthogonal_clamping_point":
        if kind != "distance":
            raise ConfigError(f"{key}.mode", mode, "'orthogonal_clamping_point' only with kind = 'distance' "
                              "(the 3D sensor writes a V.E. variable: the PLC's idealised orthogonal distance)",
                              f"not allowed for kind {kind!r}:")
        if not has_3d:
            raise ConfigError(f"{key}.mode", mode, "'orthogonal_clamping_point' only in a channel with 3D "
                              "distance control ([channel] params with configuration.decoder.function "
                              "FCT_3D_DIST_CTRL); otherwise 'axis'", "no 3D distance control for")
        axis = _axis_ref(cfg["axis"], f"{key}.axis", axes) if "axis" in cfg else None
    else:
        if "axis" not in cfg:
            raise ConfigError(f"{key}.axis", MISSING, "one of the configured axes " + ", ".join(
                repr(a) for a in axes) + " (mode 'axis': the sensor measures this axis's height)")
        axis = _axis_ref(cfg["axis"], f"{key}.axis", axes)
        if axes[axis].params.rotary:
            raise ConfigError(f"{key}.axis", cfg["axis"], "a translatory axis: the virtual machine measures a "
                              "height above a surface; a rotary distance-controlled axis (P-AXIS-00018 "
                              "ACHSTYP_ROTATOR) is supported by the cycle core, parameter lists, PLC interface, "
                              "CNC objects and NC programs, not by the simulated plant (docs/sim-models.md)",
                              "rotary axis")
    for k, only in _SENSOR_KIND_ONLY.items():
        if k in cfg and kind not in only:
            raise ConfigError(f"{key}.{k}", cfg[k], f"{k!r} only with kind = " + " or ".join(repr(o) for o in only),
                              f"not allowed for kind {kind!r}:")
    if mode == "orthogonal_clamping_point" and "footprint_radius" in cfg:
        raise ConfigError(f"{key}.footprint_radius", cfg["footprint_radius"], "only in mode 'axis' (the 3D "
                          "sensor value is the PLC's idealised orthogonal distance, FCT-M3 §12.3)",
                          "not allowed in mode 'orthogonal_clamping_point':")
    noise_std = require_number(cfg.get("noise_std", 0.0), f"{key}.noise_std", lo=0.0)
    delay = require_int(cfg.get("delay_cycles", 0), f"{key}.delay_cycles", lo=0, hi=MAX_DELAY_CYCLES)
    sensor_seed = require_int(cfg.get("seed", seed), f"{key}.seed", lo=0)
    variable = None
    range_min: float | None = None
    characteristic = None
    resolution = 0.0
    reading_at_contact = 0.0
    if kind == "encoder":
        range_min = require_number(cfg.get("range_min", -10.0), f"{key}.range_min")
        range_max = require_number(cfg.get("range_max", 10.0), f"{key}.range_max", lo=range_min, lo_open=True)
        reading_at_contact = require_number(cfg.get("reading_at_contact", 0.0), f"{key}.reading_at_contact")
    else:
        variable = _var_name(cfg.get("variable", "SENSOR"), f"{key}.variable")
        range_max = require_number(cfg.get("range_max", 10.0), f"{key}.range_max", lo=0.0, lo_open=True)
        resolution = require_number(cfg.get("resolution", 0.0), f"{key}.resolution", lo=0.0)
        fp = _footprint_keys(cfg, key, range_max, cycle_time)
        if kind == "arc_voltage":
            fp.update(_arc_keys(cfg, key, cycle_time, variable))
        if kind == "distance":
            fp.update(_linearisation_keys(cfg, key, variable, base_dir))
        if "characteristic" in cfg:
            ch = cfg["characteristic"]
            if not isinstance(ch, list):
                raise ConfigError(f"{key}.characteristic", ch,
                                  "a list of [true_mm, reported_mm] pairs, true_mm strictly increasing",
                                  "not a list:")
            try:
                DistanceSensor(cycle_time, range_max=range_max, characteristic=ch)
            except ConfigError as exc:
                raise _rekey(exc, "DistanceSensor", key) from None
            characteristic = tuple((float(a), float(b)) for a, b in ch)
    faults = []
    faults_cfg = cfg.get("faults", [])
    if not isinstance(faults_cfg, list):
        raise ConfigError(f"{key}.faults", faults_cfg, "a list of fault tables", "not a list:")
    for n, fcfg in enumerate(faults_cfg):
        fkey = f"{key}.faults[{n}]"
        require_mapping(fcfg, fkey, _FAULT_KEYS, required=("kind",))
        if "start_time" not in fcfg and "start_cycle" not in fcfg:
            raise ConfigError(f"{fkey}.start_time", MISSING, "start_time (s) or start_cycle")
        faults.append(_fault(fcfg, fkey))
    collision_depth = require_number(cfg.get("collision_depth", 0.0), f"{key}.collision_depth", lo=0.0)
    sc = SensorConfig(axis, kind, variable, noise_std, delay, sensor_seed, range_min, range_max,
                      characteristic, resolution, tuple(faults), mode, reading_at_contact, collision_depth,
                      **(fp if kind != "encoder" else {}))
    try:  # anything the models check beyond the keys above (combinations)
        sc.make_sensor(cycle_time, axes[axis].params if axis is not None else None, surface)
    except ConfigError as exc:
        model = {"encoder": "EncoderProbe", "distance": "DistanceSensor", "arc_voltage": "ArcVoltageSensor"}[kind]
        raise _rekey(exc, model, key) from None
    return sc


def _footprint_keys(cfg: dict, key: str, range_max: float, cycle_time: float) -> dict:
    """``footprint_radius``, ``field_range``, ``bursts`` of a distance or arc-voltage sensor."""
    out: dict[str, Any] = {
        "footprint_radius": require_number(cfg.get("footprint_radius", 0.0), f"{key}.footprint_radius",
                                           lo=0.0, hi=FOOTPRINT_RADIUS_MAX)}
    if "footprint_points" in cfg:
        pts = cfg["footprint_points"]
        if isinstance(pts, bool) or pts not in FOOTPRINT_POINTS:
            raise ConfigError(f"{key}.footprint_points", pts, "one of " + ", ".join(map(str, FOOTPRINT_POINTS))
                              + " (sample points of the footprint: rings of 8; fewer are faster)")
        out["footprint_points"] = int(pts)
    if "field_range" in cfg:
        out["field_range"] = require_number(cfg["field_range"], f"{key}.field_range", lo=0.0, lo_open=True)
    if "bursts" in cfg:
        bkey = f"{key}.bursts"
        b = cfg["bursts"]
        require_mapping(b, bkey, BURST_KEYS, required=("rate", "duration", "amplitude"))
        rate_max = 1.0 / cycle_time
        out["bursts"] = Bursts(
            rate=require_number(b["rate"], f"{bkey}.rate", lo=0.0, hi=rate_max),
            duration=require_number(b["duration"], f"{bkey}.duration", lo=cycle_time, hi=60.0),
            amplitude=require_number(b["amplitude"], f"{bkey}.amplitude", lo=0.0, hi=range_max),
            offset=require_number(b.get("offset", 0.0), f"{bkey}.offset", lo=-range_max, hi=range_max))
    return out


def _linearisation_keys(cfg: dict, key: str, variable: str, base_dir: Path) -> dict:
    """``linearisation`` (a table of [reading_mm, distance_mm] pairs, or a TOML file with one) and
    ``raw_variable`` of a distance sensor (issue 16, docs/process.md *Calibration run*)."""
    from distctrl.plc.linearisation import check_table
    if "linearisation" not in cfg:
        if "raw_variable" in cfg:
            raise ConfigError(f"{key}.raw_variable", cfg["raw_variable"], "only with sensor.linearisation (the "
                              "sensor writes its reading there, the PLC's table the distance)", "not used:")
        return {}
    table = cfg["linearisation"]
    lkey, file = f"{key}.linearisation", None
    if isinstance(table, str):
        file = _file(table, lkey, base_dir, "linearisation table (TOML with linearisation = [[reading_mm, "
                                            "distance_mm], ...], as distctrl calibrate writes it)")
        try:
            data = tomllib.loads(file.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
            raise ConfigError(lkey, table, "a TOML file with linearisation = [[reading_mm, distance_mm], ...]",
                              f"unreadable ({exc}):") from None
        if "linearisation" not in data:
            raise ConfigError(lkey, table, "a TOML file with a top-level key linearisation = [[reading_mm, "
                              "distance_mm], ...]", "no linearisation key in")
        lkey, table = f"{lkey} ({file.name})", data["linearisation"]
    out = {"linearisation": check_table(table, lkey), "linearisation_file": file,
           "raw_variable": _var_name(cfg.get("raw_variable", "SENSOR_RAW"), f"{key}.raw_variable")}
    if out["raw_variable"] == variable:
        raise ConfigError(f"{key}.raw_variable", cfg.get("raw_variable", "SENSOR_RAW"),
                          f"a V.E. variable other than the distance variable {variable!r} (sensor.variable): the "
                          "sensor writes its reading, the PLC's linearisation the distance", "the same as variable:")
    return out


def _arc_keys(cfg: dict, key: str, cycle_time: float, variable: str) -> dict:
    """The arc-voltage keys (V, V/mm, Hz) and the PLC linearisation's parameters."""
    from distctrl.plc.arc_voltage import ARC_K_RANGE, ARC_V0_RANGE
    nyquist = 0.5 / cycle_time
    out: dict[str, Any] = {
        "voltage_variable": _var_name(cfg.get("voltage_variable", "ARC_VOLTAGE"), f"{key}.voltage_variable"),
        "arc_v0": require_number(cfg.get("arc_v0", 100.0), f"{key}.arc_v0", lo=ARC_V0_RANGE[0], hi=ARC_V0_RANGE[1]),
        "arc_k": require_number(cfg.get("arc_k", 6.0), f"{key}.arc_k", lo=ARC_K_RANGE[0], hi=ARC_K_RANGE[1]),
        "arc_ripple": require_number(cfg.get("arc_ripple", 0.0), f"{key}.arc_ripple", lo=0.0, hi=ARC_RIPPLE_MAX),
        "arc_noise_std": require_number(cfg.get("arc_noise_std", 0.0), f"{key}.arc_noise_std", lo=0.0,
                                        hi=ARC_RIPPLE_MAX),
        "kerf_jump": require_number(cfg.get("kerf_jump", 0.0), f"{key}.kerf_jump", lo=0.0, hi=KERF_JUMP_MAX),
        "arc_speed_volts": require_number(cfg.get("arc_speed_volts", 0.0), f"{key}.arc_speed_volts", lo=0.0,
                                          hi=ARC_SPEED_VOLTS_MAX),
        "arc_speed_tau": require_number(cfg.get("arc_speed_tau", 0.02), f"{key}.arc_speed_tau", lo=0.0, hi=1.0)}
    if "arc_cut_speed" in cfg:
        out["arc_cut_speed"] = require_number(cfg["arc_cut_speed"], f"{key}.arc_cut_speed", lo=0.0, lo_open=True,
                                              hi=ARC_CUT_SPEED_MAX)
    elif out["arc_speed_volts"]:
        raise ConfigError(f"{key}.arc_cut_speed", MISSING, f"the cut speed in mm/s (0 .. {ARC_CUT_SPEED_MAX:g}] at "
                          "which the slow-down rise is 0: required with arc_speed_volts > 0")
    hz = cfg.get("arc_ripple_hz", 50.0)
    try:
        out["arc_ripple_hz"] = require_number(hz, f"{key}.arc_ripple_hz", lo=0.0, hi=nyquist, lo_open=True,
                                              hi_open=True)
    except ConfigError as exc:
        raise ConfigError(f"{key}.arc_ripple_hz", hz, f"a frequency in (0, {nyquist:g}) Hz: below half the cycle "
                          f"rate (cycle_time = {cycle_time:g} s)", exc.problem) from None
    if "plc_v0" in cfg:
        out["plc_v0"] = require_number(cfg["plc_v0"], f"{key}.plc_v0", lo=ARC_V0_RANGE[0], hi=ARC_V0_RANGE[1])
    if "plc_k" in cfg:
        out["plc_k"] = require_number(cfg["plc_k"], f"{key}.plc_k", lo=ARC_K_RANGE[0], hi=ARC_K_RANGE[1])
    if out["voltage_variable"] == variable:
        raise ConfigError(f"{key}.voltage_variable", cfg.get("voltage_variable", "ARC_VOLTAGE"),
                          f"a V.E. variable other than the distance variable {variable!r} (sensor.variable): the "
                          "sensor writes the voltage, the PLC linearisation the distance", "the same as variable:")
    return out


def _channel_config(cfg: object, axes: dict[str, AxisConfig], base_dir: Path
                    ) -> tuple[ChannelParameters | None, Path | None, tuple[str, ...], str | None]:
    """``[channel]``: (channel parameters, their file, loader warnings, kinematics or None)."""
    key = "channel"
    require_mapping(cfg, key, CHANNEL_KEYS)
    assert isinstance(cfg, dict)
    params, params_file, warnings = None, None, ()
    if "params" in cfg:
        params_file = _file(cfg["params"], f"{key}.params", base_dir,
                            "channel parameter list (kernel format)")
        try:
            plist = load_channel_list(params_file)
        except ParameterError as exc:
            exc.scenario_key = f"{key}.params"  # type: ignore[attr-defined]  # see _with_source
            raise
        params, warnings = plist.params, tuple(plist.warnings)
    missing = [a for a in CA_AXES if a not in axes]
    if "kinematics" in cfg:
        value = cfg["kinematics"]
        kin = require_choice(value.upper() if isinstance(value, str) and value.upper() == "CA" else value,
                             f"{key}.kinematics", KINEMATICS)
        if kin == "CA" and missing:
            raise ConfigError(f"{key}.kinematics", value, "'CA' only with the axes X, Y, Z, A and C "
                              f"configured (missing: {', '.join(missing)}); or 'none'", "axes missing for")
    else:
        kin = "CA" if not missing else "none"
    return params, params_file, warnings, (None if kin == "none" else kin)


def _event(n: int, cfg: object, axes: dict[str, AxisConfig], sensor: SensorConfig | None,
           duration: float | None, base_dir: Path = Path(".")) -> Event:
    key = f"events[{n}]"
    actions = tuple(EVENT_KINDS)
    require_mapping(cfg, key, ("t",) + actions, required=("t",))
    assert isinstance(cfg, dict)
    t_hi = duration
    t = require_number(cfg["t"], f"{key}.t", lo=0.0, hi=t_hi)
    given = [k for k in cfg if k != "t"]
    if not given:
        raise ConfigError(key, MISSING, "exactly one action key: " + ", ".join(actions))
    if len(given) > 1:
        raise ConfigError(key, given, "exactly one action key per event (one of " + ", ".join(actions)
                          + "); use one [[events]] table per action", "more than one action:")
    kind = given[0]
    akey = f"{key}.{kind}"
    keys, required = EVENT_KINDS[kind]
    body = cfg[kind]
    require_mapping(body, akey, keys, required)
    assert isinstance(body, dict)
    data: dict[str, Any]
    if kind == "plc":
        data = {"axis": _axis_ref(body["axis"], f"{akey}.axis", axes),
                "transition": _transition(body["transition"], f"{akey}.transition"),
                "position": require_number(body.get("position", 0.0), f"{akey}.position")}
    elif kind == "override":
        axis = body.get("axis")
        if axis is not None:
            axis = _axis_ref(axis, f"{akey}.axis", axes)
        hi = OVERRIDE_AXIS_MAX if axis is not None else OVERRIDE_PATH_MAX
        value = body["value"]
        try:
            value = require_number(value, f"{akey}.value", lo=0.0, hi=hi)
        except ConfigError as exc:
            what = "axis feed override" if axis is not None else "channel path override (no axis)"
            raise ConfigError(f"{akey}.value", value, f"{what}: a number in [0, {hi:g}]",
                              exc.problem) from None
        data = {"axis": axis, "value": value}
    elif kind == "feed_hold":
        data = {"axis": _axis_ref(body["axis"], f"{akey}.axis", axes),
                "value": _bool(body.get("value", True), f"{akey}.value")}
    elif kind == "reset":
        data = {}
    elif kind == "start":
        # CNC start of a program (docs/scenarios.md): the scenario's own one, or another file / text
        if "program" in body and "program_text" in body:
            raise ConfigError(f"{akey}.program_text", "...", "at most one of 'program' (a file) or "
                              "'program_text'", "both 'program' and")
        if "program" in body:
            data = {"program": str(_file(body["program"], f"{akey}.program", base_dir, "NC program file"))}
        elif "program_text" in body:
            text = body["program_text"]
            if not isinstance(text, str):
                raise ConfigError(f"{akey}.program_text", text, "the NC program as a string", "not a string:")
            data = {"program_text": text}
        else:
            data = {}
    elif kind in ("axis_error", "axis_release"):
        data = {"axis": _axis_ref(body["axis"], f"{akey}.axis", axes)}
    elif kind == "sensor_fault":
        if sensor is None:
            raise ConfigError(akey, body, "a sensor_fault event needs a [sensor] table", "no sensor for")
        fault = _fault(body, akey, start_time=t)  # validates; Fault(**data) rebuilds it (start: t)
        data = {k: (int(getattr(fault, k)) if k == "duration_cycles"
                    else float(getattr(fault, k)) if k in ("value", "duration", "rate")
                    else getattr(fault, k)) for k in keys if k in body}
    elif kind == "variable":
        data = {"name": _var_name(body["name"], f"{akey}.name"),
                "value": require_number(body["value"], f"{akey}.value")}
    else:  # plc_cyclic
        axis = _axis_ref(body["axis"], f"{akey}.axis", axes)
        has = [k for k in ("position", "distance") if k in body]
        if len(has) != 1:
            problem = "neither position nor distance in" if not has else "both position and distance in"
            raise ConfigError(akey, body, "exactly one of 'position' (D_Position, mm) or 'distance' "
                              "(D_Distance, mm) besides 'axis'", problem)
        data = {"axis": axis, has[0]: require_number(body[has[0]], f"{akey}.{has[0]}")}
    return Event(t, kind, data, n)


def _build(data: object, base_dir: Path, path: Path | None) -> Scenario:
    require_mapping(data, "scenario", TOP_LEVEL_KEYS)
    assert isinstance(data, dict)
    default_name = path.stem if path is not None else "scenario"
    name = _string(data.get("name", default_name), "name", "a non-empty string")
    cycle_time = require_number(data.get("cycle_time", 0.001), "cycle_time",
                                lo=CYCLE_TIME_MIN, hi=CYCLE_TIME_MAX)

    has_file, has_text = "program" in data, "program_text" in data
    if has_file and has_text:
        raise ConfigError("program_text", data["program_text"][:40] if isinstance(data["program_text"], str)
                          else data["program_text"], "exactly one of 'program' (a file) or 'program_text'",
                          "both 'program' and")
    if not has_file and not has_text:
        raise ConfigError("program", MISSING, "exactly one of 'program' (NC file, relative to the "
                          "scenario) or 'program_text' (the NC program inline)")
    if has_file:
        program_file: Path | None = _file(data["program"], "program", base_dir, "NC program file")
        try:
            program_text = program_file.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            program_text = program_file.read_text(encoding="latin-1")
        except OSError as exc:
            raise ConfigError("program", data["program"], "a readable NC program file",
                              f"cannot read ({exc.strerror}):") from None
    else:
        program_file = None
        program_text = data["program_text"]
        if not isinstance(program_text, str):
            raise ConfigError("program_text", program_text, "the NC program as a string", "not a string:")

    duration = None
    if "duration" in data:
        duration = require_number(data["duration"], "duration", lo=0.0, lo_open=True)
    settle_time = require_number(data.get("settle_time", 0.5), "settle_time", lo=0.0)
    seed = require_int(data.get("seed", 0), "seed", lo=0)

    variables_cfg = data.get("variables", {})
    if not isinstance(variables_cfg, dict):
        raise ConfigError("variables", variables_cfg, "a table NAME = number", "not a table:")
    variables: dict[str, float] = {}
    for k, v in variables_cfg.items():
        var = _var_name(k, f"variables.{k}")
        variables[var] = require_number(v, f"variables.{k}")

    tool_cfg = data.get("tool", {})
    require_mapping(tool_cfg, "tool", ("length",))
    tool_length = require_number(tool_cfg.get("length", 0.0), "tool.length")

    if "axes" not in data:
        raise ConfigError("axes", MISSING, "at least one axis table [axes.X] .. [axes.C]")
    axes_cfg = data["axes"]
    require_mapping(axes_cfg, "axes", AXIS_NAMES)
    if not axes_cfg:
        raise ConfigError("axes", axes_cfg, "at least one axis table [axes.X] .. [axes.C]", "empty:")
    axes = {n: _axis_config(n, axes_cfg[n], base_dir, cycle_time) for n in AXIS_NAMES if n in axes_cfg}

    surface_cfg = data.get("surface", {})
    surface = surface_from_config(surface_cfg, base_dir, key="surface")

    channel_params, channel_file, channel_warnings, kinematics = None, None, (), None
    if "channel" in data:
        channel_params, channel_file, channel_warnings, kinematics = _channel_config(data["channel"], axes,
                                                                                     base_dir)
    elif all(a in axes for a in CA_AXES):
        kinematics = "CA"
    has_3d = channel_params is not None and channel_params.fct_3d_dist_ctrl

    sensor = None
    if "sensor" in data:
        sensor = _sensor_config(data["sensor"], axes, seed, cycle_time, has_3d, surface, base_dir)

    events_cfg = data.get("events", [])
    if not isinstance(events_cfg, list):
        raise ConfigError("events", events_cfg, "a list of event tables ([[events]])", "not a list:")
    events = [_event(n, e, axes, sensor, duration, base_dir) for n, e in enumerate(events_cfg)]
    events.sort(key=lambda e: e.t)  # stable

    extv, extv_file = None, None
    if "external_variables" in data:
        extv_file = _file(data["external_variables"], "external_variables", base_dir,
                          "external-variable list (FCT-M3 §12.8.4)")
        try:
            extv = load_external_variables(extv_file)
        except ParameterError as exc:
            exc.scenario_key = "external_variables"  # type: ignore[attr-defined]  # see _with_source
            raise
        _check_declared(extv, extv_file, variables, sensor, events)
        for declared in extv:
            variables.setdefault(declared, 0.0)

    # issue 16: [[process]] tables (docs/process.md)
    processes: tuple = ()
    if "process" in data:
        from distctrl.plc.process import process_configs
        processes = process_configs(data["process"], axes, sensor, cycle_time, has_3d)

    return Scenario(path, base_dir, name, cycle_time, program_text, program_file, duration, settle_time, seed,
                    variables, tool_length, axes, surface, dict(surface_cfg), sensor, events, channel_params,
                    channel_file, channel_warnings, kinematics, extv, extv_file, processes=processes)


def _check_declared(extv: dict, extv_file: Path, variables: dict, sensor, events) -> None:
    """With an external-variable list, every V.E. name of the scenario must be declared in it."""
    allowed = f"a variable declared in {extv_file.name} ({', '.join(extv) or 'none declared'})"
    for name in variables:
        if name not in extv:
            raise ConfigError(f"variables.{name}", name, allowed, "not declared:")
    if sensor is not None and sensor.variable is not None and sensor.variable not in extv:
        raise ConfigError("sensor.variable", sensor.variable, allowed, "not declared:")
    if sensor is not None and sensor.voltage_variable is not None and sensor.voltage_variable not in extv:
        raise ConfigError("sensor.voltage_variable", sensor.voltage_variable, allowed, "not declared:")
    if sensor is not None and sensor.raw_variable is not None and sensor.raw_variable not in extv:
        raise ConfigError("sensor.raw_variable", sensor.raw_variable, allowed, "not declared:")
    for ev in events:
        if ev.kind == "variable" and ev.data["name"] not in extv:
            raise ConfigError(f"events[{ev.index}].name", ev.data["name"], allowed, "not declared:")


def _with_source(source: str, data: object, base_dir: Path, path: Path | None) -> Scenario:
    try:
        return _build(data, base_dir, path)
    except ScenarioError:
        raise
    except ParameterError as exc:
        # Keep the list's own "file:line: ..." message; say where in the scenario it came from.
        key = getattr(exc, "scenario_key", None)
        if key is not None:
            exc.args = (f"{exc.args[0]} (parameter list of {key} in {source})",) + exc.args[1:]
        raise
    except ConfigError as exc:
        key = exc.key
        if key.startswith("scenario."):  # top-level keys are reported bare
            key = key[len("scenario."):]
        raise ScenarioError(source, key, exc.value, exc.allowed, exc.problem) from None


# --- entry points -------------------------------------------------------------------------------------
def scenario_from_dict(data: dict, base_dir: str | os.PathLike = ".", source: str = "<dict>") -> Scenario:
    """Validate a scenario given as a plain dict (the parsed TOML). Paths are relative to ``base_dir``;
    ``source`` names the origin in error messages."""
    return _with_source(source, data, Path(base_dir), None)


def _parse_toml(text: str, source: str) -> dict:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        msg = str(exc)
        m = _TOML_LINE_RE.search(msg)
        # tomllib says "(at end of document)" instead of a line when the text ends too early
        line = int(m.group(1)) if m else (max(1, len(text.splitlines())) if "end of document" in msg else None)
        raise ScenarioError(source, "toml", msg, "valid TOML (https://toml.io/en/v1.0.0)", "syntax error:",
                            line=line) from None


def scenario_from_text(toml_text: str, base_dir: str | os.PathLike = ".",
                       source: str = "<string>") -> Scenario:
    """Parse and validate scenario TOML text (paths relative to ``base_dir``)."""
    return _with_source(source, _parse_toml(toml_text, source), Path(base_dir), None)


def load_scenario(path: str | os.PathLike) -> Scenario:
    """Load and validate a scenario file; relative paths inside are relative to its directory."""
    p = Path(path)
    source = str(p)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise ScenarioError(source, "file", source, "a readable TOML scenario file",
                            f"cannot read ({exc.strerror}):") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise ScenarioError(source, "file", raw[exc.start:exc.start + 8], "UTF-8 text (TOML)",
                            "not UTF-8:", line=line) from None
    return _with_source(source, _parse_toml(text, source), p.parent, p)
