"""``[sensor]``: the height sensor (encoder-2 probe, distance sensor, plasma arc voltage), its
faults, footprint, bursts and the PLC's linearisation (:class:`SensorConfig`; docs/scenarios.md,
docs/sim-models.md)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

from distctrl.base.text import read_text
from distctrl.errors.config import (MAX_DELAY_CYCLES, MISSING, ConfigError, require_choice, require_int,
                                    require_mapping, require_number)
from distctrl.params.axis import AxisParameters
from distctrl.plc.arc_voltage import ARC_K_RANGE, ARC_V0_RANGE, ArcVoltageLinearisation
from distctrl.plc.linearisation import DistanceLinearisation, check_table
from distctrl.sim.sensors import (FAULT_KINDS, FOOTPRINT_POINTS, ArcVoltageSensor, Bursts, DistanceSensor, EncoderProbe,
                                  Fault, SensorBase)
from distctrl.sim.surface import Surface

from .axes import AxisConfig
from .common import _axis_ref, _file, _rekey, _var_name

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
_FAULT_KEYS = ("kind", "start_time", "start_cycle", "duration", "duration_cycles", "value", "rate")


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
            return DistanceLinearisation(self.linearisation, f"V.E.{self.raw_variable}", f"V.E.{self.variable}")
        if self.kind != "arc_voltage":
            return None
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
            data = tomllib.loads(read_text(file, fallback=None))     # UTF-8, a BOM skipped
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
