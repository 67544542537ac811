"""The whole scenario: the top-level keys, :class:`Scenario`, ``_build`` (which reads each section
through its module) and the entry points :func:`load_scenario`, :func:`scenario_from_text` and
:func:`scenario_from_dict`, which turn a :class:`ConfigError` into a :class:`ScenarioError` naming
the file (and the TOML line of a syntax error)."""
from __future__ import annotations

import codecs
import os
import re
from dataclasses import dataclass
from pathlib import Path

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

from distctrl.base.text import decode_text, read_text
from distctrl.errors import ParameterError
from distctrl.errors.config import MISSING, ConfigError, require_int, require_mapping, require_number
from distctrl.params.channel import ChannelParameters
from distctrl.params.external_variables import load_external_variables
from distctrl.plc.process import make_process_program, process_configs
from distctrl.sim.drive import Drive
from distctrl.sim.interpolator import AxisLimits
from distctrl.sim.sensors import SensorBase
from distctrl.sim.surface import Surface, surface_from_config

from .axes import AXIS_NAMES, AxisConfig, _axis_config
from .channel import CA_AXES, _channel_config
from .common import ScenarioError, _file, _string, _var_name
from .events import Event, _event
from .sensor import SensorConfig, _sensor_config

TOP_LEVEL_KEYS = ("name", "cycle_time", "program", "program_text", "duration", "settle_time", "seed",
                  "variables", "external_variables", "tool", "axes", "channel", "surface", "sensor", "events",
                  "process")                      # issue 16: [[process]] tables (docs/process.md)
CYCLE_TIME_MIN, CYCLE_TIME_MAX = 1e-4, 0.1
_TOML_LINE_RE = re.compile(r"at line (\d+)")


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
            program_text = read_text(program_file)      # UTF-8 (a BOM skipped) or Latin-1
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
    raw = raw.removeprefix(codecs.BOM_UTF8)         # a BOM (Windows editors) is not TOML
    try:
        text = decode_text(raw, fallback=None)
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise ScenarioError(source, "file", raw[exc.start:exc.start + 8], "UTF-8 text (TOML)",
                            "not UTF-8:", line=line) from None
    return _with_source(source, _parse_toml(text, source), p.parent, p)
