"""``[axes.X]`` .. ``[axes.C]``: each axis's parameter list, drive and interpolation data
(:class:`AxisConfig`; docs/scenarios.md)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from distctrl.errors import ParameterError
from distctrl.errors.config import MAX_DELAY_CYCLES, ConfigError, require_int, require_mapping, require_number
from distctrl.params.axis import AxisParameters
from distctrl.params.listfile import load_list
from distctrl.sim.drive import Drive
from distctrl.sim.interpolator import AxisLimits

from .common import _file

#: axis names a scenario may configure (the order is the display order)
AXIS_NAMES = ("X", "Y", "Z", "A", "B", "C")
AXIS_KEYS = ("params", "start", "kv", "v_max", "a_max", "v_rapid", "a_rapid", "bus_delay_cycles",
             "resolution", "feedforward",
             "resonance_hz", "damping")           # the drive's mechanical resonance (issue 15)


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
