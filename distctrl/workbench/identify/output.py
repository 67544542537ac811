"""``distctrl identify``, the output: JSON, summary, the fitted scenario TOML, the report."""
from __future__ import annotations

import base64
import math
import os
from pathlib import Path

from ..pages import render
from .common import IdentifyError
from .result import UNITS, Identification, result_json, uncertainty_json  # noqa: F401  (part of the API)


def _pm(res: Identification, group: str, key: str, scale: float, spec: str, unit: str) -> str:
    """'  ± sd unit' when the figure is identified and has a standard deviation."""
    values = res.drive if group == "drive" else res.sensor
    sd = (res.uncertainty or {}).get(group, {}).get(key)
    if values.get(key) is None or sd is None or not math.isfinite(sd):
        return ""
    return f"  ± {sd * scale:{spec}} {unit}".rstrip()


def _fmt(v, scale=1.0, spec=".4g", unit=""):
    return "-" if v is None else f"{v * scale:{spec}} {unit}".rstrip()


def _bound(res: Identification, key: str, unit: str) -> str:
    b = res.extra.get(f"{key}_lower_bound")
    if res.drive.get(key) is not None or b is None:
        return ""
    return f"  (at least {b:.4g} {unit}: what the {res.extra.get('limits_lower_bound_from')} reached)"


def format_summary(res: Identification) -> str:
    d, s = res.drive, res.sensor
    ch = s["characteristic"]
    lines = [f"identified at cycle {res.cycle_time * 1e3:g} ms from {len(res.recordings)} recording(s)",
             "drive:",
             f"  kv            {_fmt(d['kv'], unit='1/s')}{_pm(res, 'drive', 'kv', 1, '.2g', '1/s')}",
             f"  dead time     {_fmt(d['dead_time'], 1e3, '.3g', 'ms')}{_pm(res, 'drive', 'dead_time', 1e3, '.2g', 'ms')}",
             f"  feed-forward  {_fmt(d.get('feedforward'), spec='.3g')}"
             f"{_pm(res, 'drive', 'feedforward', 1, '.2g', '')}",
             f"  v_max         {_fmt(d['v_max'], unit='mm/s')}{_bound(res, 'v_max', 'mm/s')}",
             f"  a_max         {_fmt(d['a_max'], unit='mm/s^2')}{_bound(res, 'a_max', 'mm/s^2')}",
             f"  resonance     {_fmt(d['resonance_hz'], unit='Hz')}{_pm(res, 'drive', 'resonance_hz', 1, '.2g', 'Hz')}",
             f"  damping       {_fmt(d['damping'], spec='.3g')}{_pm(res, 'drive', 'damping', 1, '.2g', '')}",
             "sensor:" + f" ({res.extra.get('sensor_reads', '')})",
             f"  delay         {_fmt(s['delay'], 1e3, '.3g', 'ms')}{_pm(res, 'sensor', 'delay', 1e3, '.2g', 'ms')}",
             f"  noise std     {_fmt(s['noise_std'], 1e3, '.3g', 'um')}{_pm(res, 'sensor', 'noise_std', 1e3, '.2g', 'um')}",
             "  characteristic " + ("-" if ch is None else
                                    f"{len(ch)} points, true {ch[0][0]:.3f} .. {ch[-1][0]:.3f} mm, "
                                    f"reported - true {min(b - a for a, b in ch) * 1e3:+.1f} .. "
                                    f"{max(b - a for a, b in ch) * 1e3:+.1f} um"),
             "fit quality:"]
    f = res.fit
    if f.get("drive_fit_percent"):
        lines.append("  drive (actual, simulated from the command): " + ", ".join(
            f"{_fmt(p, spec='.1f', unit='%')} (RMS {_fmt(e, 1e3, '.3g', 'um')})"
            for p, e in zip(f["drive_fit_percent"], f["drive_rms_mm"])))
    if f.get("frf_fit_percent") is not None:
        band = res.extra.get("frequency_band_hz") or [math.nan, math.nan]
        lines.append(f"  motor -> sensor frequency response: {f['frf_fit_percent']:.1f} % "
                     f"(coherent {band[0]:.1f} .. {band[1]:.1f} Hz)")
    for v in (res.validation or {}).get("recordings", []):
        parts = []
        if v.get("drive_fit_percent") is not None:
            parts.append(f"drive {v['drive_fit_percent']:.1f} % (RMS {v['drive_rms_mm'] * 1e3:.3g} um)")
        if v.get("sensor_rms_mm") is not None:
            parts.append(f"sensor RMS {v['sensor_rms_mm'] * 1e3:.3g} um"
                         + (f" ({v['sensor_rms_over_noise']:.2f} x the noise)" if v.get("sensor_rms_over_noise")
                            else ""))
        lines.append(f"  validation {v['path']} (not fitted): " + ", ".join(parts))
    if f.get("sensor_rms_mm"):
        lines.append("  sensor (predicted from the actual): RMS " + ", ".join(
            _fmt(e, 1e3, ".3g", "um") for e in f["sensor_rms_mm"]))
    return "\n".join(lines) + "\n"


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise IdentifyError(f"cannot write {v!r} to TOML")
        return repr(v)
    if isinstance(v, str):
        if "\n" in v:
            return '"""\n' + v.replace("\\", "\\\\").replace('"""', '\\"\\"\\"') + '"""'
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise IdentifyError(f"cannot write {type(v).__name__} to TOML")


def _toml_key(k: str) -> str:
    return k if k.replace("_", "").replace("-", "").isalnum() else _toml_value(k)


def toml_text(doc: dict, comments: dict | None = None) -> str:
    """A TOML document of the scenario subset: plain keys, tables, tables of tables, arrays of tables."""
    comments = comments or {}
    out: list[str] = []

    def table(prefix: str, d: dict) -> None:
        plain = {k: v for k, v in d.items() if not isinstance(v, dict) and not _is_table_array(v)}
        if prefix and (plain or not d):
            out.append(f"\n[{prefix}]")
        for k, v in plain.items():
            c = comments.get(f"{prefix}.{k}" if prefix else k)
            out.append(f"{_toml_key(k)} = {_toml_value(v)}" + (f"    # {c}" if c else ""))
        for k, v in d.items():
            if isinstance(v, dict):
                table(f"{prefix}.{_toml_key(k)}" if prefix else _toml_key(k), v)
            elif _is_table_array(v):
                for item in v:
                    out.append(f"\n[[{prefix + '.' if prefix else ''}{_toml_key(k)}]]")
                    for kk, vv in item.items():
                        out.append(f"{_toml_key(kk)} = {_toml_value(vv)}")
    table("", doc)
    return "\n".join(out).lstrip("\n") + "\n"


def _is_table_array(v) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)


DEFAULT_PROGRAM = """%IDENTIFIED
; the fitted plant: CONST_DIST 1 mm over a sheet with a 0.5 mm step at X 150
N10 G90 G0 X0 Y0 Z{z0:g}
N20 Z[DIST_CTRL ON CONST_DIST SET_DIST=1 SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]
N30 G1 X300 F6000
N40 Z[DIST_CTRL OFF]
N50 G0 Z{z1:g}
N60 M30
"""

DEFAULT_LIST = """# Z axis: distance control on, a distance sensor as a V.E. variable (written by distctrl identify;
# tune kp, d_tv and the filter with distctrl tune/step/margins on the fitted plant)
lr_param.distance_control_on        1
kenngr.distc.max_deviation          80000     # [0.1 um] 8 mm
kenngr.distc.v_max                  100000    # [um/s] 100 mm/s
kenngr.distc.a_max                  10000     # [mm/s^2]
kenngr.distc.max_act_value_change   10000000  # [um/s]
kenngr.distc.max_pos                100000    # [0.1 um] +10 mm
kenngr.distc.min_pos                -100000   # [0.1 um] -10 mm
kenngr.distc.filter_type            MOVING_AVERAGE
kenngr.distc.n_cycles               4
kenngr.distc.kp                     0.05      # conservative: tune it on the fitted plant
"""


def fitted_axis(res: Identification) -> tuple[dict, list[str]]:
    """The scenario's axis keys of the fitted drive (only the identified ones) and notes."""
    T = res.cycle_time
    d = res.drive
    keys: dict = {}
    notes: list[str] = []
    if d["kv"] is not None:
        # the simulator's drive integrates x += kv (c - x) T: the same pole as the continuous kv
        keys["kv"] = float(-math.expm1(-d["kv"] * T) / T)
        keys["bus_delay_cycles"] = int(round(d["dead_time"] / T))
        if d.get("feedforward") is not None:
            # the fit's feed-forward is the simulator's own (v = kv (c_k - x) + ff (c_k - c_k-1) / T)
            keys["feedforward"] = float(min(max(d["feedforward"], 0.0), 1.0))
    if d["v_max"] is not None:
        keys["v_max"] = float(d["v_max"])
    if d["a_max"] is not None:
        keys["a_max"] = float(d["a_max"])
    if d["resonance_hz"] is not None:
        if d["resonance_hz"] <= 1.0 / (4.0 * T):
            keys["resonance_hz"] = float(d["resonance_hz"])
            keys["damping"] = float(min(max(d["damping"], 1e-4), 1.0))
        else:
            notes.append(f"resonance {d['resonance_hz']:.1f} Hz above 1/(4T) = {0.25 / T:g} Hz: not written")
    return keys, notes


def _limit_keys(res: Identification, ax: dict, notes: list[str]) -> dict:
    """v_max / a_max the recordings did not identify (audit R7: never the defaults silently): the
    template's configured value if it has one, else the lower bound the recordings show (what the command,
    or the motor, reached without the drive saturating). Writes them into ``ax``; returns their comments."""
    comments = {}
    source = res.extra.get("limits_lower_bound_from")
    for key, unit in (("v_max", "mm/s"), ("a_max", "mm/s^2")):
        if res.drive.get(key) is not None:
            comments[key] = f"{unit}, identified"
            continue
        bound = res.extra.get(f"{key}_lower_bound")
        if key in ax:
            comments[key] = (f"{unit}, the template's configured value (not identified"
                             + (f"; the recordings show at least {bound:.4g})" if bound is not None else ")"))
        elif bound is not None:
            ax[key] = float(f"{bound:.6g}")
            comments[key] = (f"{unit}, lower bound: the {source} reached this without the drive saturating; "
                             f"the drive's own limit was not seen")
            notes.append(f"{key} = {bound:.4g} {unit} written as a lower bound (what the {source} reached; the "
                         f"drive's own limit was not identified)")
        else:
            notes.append(f"{key}: neither identified nor bounded: the simulator's default applies "
                         f"(docs/scenarios.md)")
    return comments


def fitted_sensor(res: Identification, range_max: float = 10.0) -> dict:
    """The scenario's sensor keys of the fitted sensor."""
    T = res.cycle_time
    s = res.sensor
    keys: dict = {}
    if s["delay"] is not None:
        keys["delay_cycles"] = int(round(s["delay"] / T))
    if s["noise_std"] is not None:
        keys["noise_std"] = float(s["noise_std"])
    ch = s["characteristic"]
    if ch is not None and len(ch) >= 2:
        pts = [list(p) for p in ch if 0.0 < p[0] < range_max]
        if len(pts) >= 2:
            # extended linearly from the end segments to 0 and range_max: the simulator holds the
            # end values beyond the table
            (x0, y0), (x1, y1) = pts[0], pts[1]
            (xa, ya), (xb, yb) = pts[-2], pts[-1]
            head = [[0.0, round(y0 - x0 * (y1 - y0) / (x1 - x0), 6)]]
            tail = [[float(range_max), round(yb + (range_max - xb) * (yb - ya) / (xb - xa), 6)]]
            keys["characteristic"] = head + pts + tail
    return keys


def _absolute_paths(doc: dict, base: Path) -> None:
    def fix(d: dict, key: str) -> None:
        v = d.get(key)
        if isinstance(v, str) and v and not os.path.isabs(v):
            d[key] = str((base / v).resolve())
    fix(doc, "program")
    for ax in (doc.get("axes") or {}).values():
        if isinstance(ax, dict):
            fix(ax, "params")
    if isinstance(doc.get("channel"), dict):
        fix(doc["channel"], "params")
    for feat in ((doc.get("surface") or {}).get("features") or []):
        if isinstance(feat, dict):
            fix(feat, "file")


def write_scenario(res: Identification, out_dir: str | os.PathLike, template: str | os.PathLike | None = None,
                   axis: str = "Z", name: str = "fitted.toml") -> tuple[Path, list[str]]:
    """The fitted machine and sensor as a complete scenario TOML in ``out_dir`` (with its parameter
    list when no template is given). Returns the path and notes (what was not written)."""
    # tomllib (Python >= 3.11) only to read a template; without it (3.10) the rest of identify works
    import tomllib

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    axis_keys, notes = fitted_axis(res)
    if template is not None:
        tp = Path(template)
        try:
            doc = tomllib.loads(tp.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError) as exc:
            raise IdentifyError(f"--template {tp}: cannot read: {getattr(exc, 'strerror', None) or exc}") from None
        except tomllib.TOMLDecodeError as exc:
            raise IdentifyError(f"--template {tp}: not valid TOML: {exc}") from None
        _absolute_paths(doc, tp.resolve().parent)
        sensor = doc.get("sensor")
        if not isinstance(sensor, dict):
            raise IdentifyError(f"--template {tp}: no [sensor] table; the template must have a sensor")
        axis = sensor.get("axis", axis)
        axes = doc.setdefault("axes", {})
        if axis not in axes:
            raise IdentifyError(f"--template {tp}: no [axes.{axis}] (the sensor's axis)")
        doc["name"] = f"{doc.get('name', tp.stem)} (plant fitted by distctrl identify)"
    else:
        z0 = 31.5
        doc = {"name": "Plant fitted by distctrl identify: CONST_DIST 1 mm over a sheet with a 0.5 mm step",
               "cycle_time": float(f"{res.cycle_time:.9g}"), "duration": 5.0,
               "program_text": DEFAULT_PROGRAM.format(z0=z0, z1=z0 + 8.5),
               "axes": {"X": {"start": 0.0, "v_max": 500.0, "a_max": 5000.0}, "Y": {"start": 0.0},
                        axis: {"params": "z_axis.lis", "start": z0}},
               "surface": {"base": 30.0, "features": [{"type": "step", "axis": "X", "at": 150.0, "height": 0.5}]},
               "sensor": {"axis": axis, "kind": "distance", "variable": "SENSOR", "range_max": 10.0, "seed": 1}}
        (out / "z_axis.lis").write_text(DEFAULT_LIST, encoding="utf-8")
        sensor = doc["sensor"]
    if abs(float(doc.get("cycle_time", 0.001)) - res.cycle_time) > 1e-3 * res.cycle_time:
        notes.append(f"the template's cycle_time {doc.get('cycle_time', 0.001)} s differs from the recordings' "
                     f"{res.cycle_time:g} s: cycle_time set to the recordings'")
        doc["cycle_time"] = float(f"{res.cycle_time:.9g}")
    doc["axes"][axis].update(axis_keys)
    limit_comments = _limit_keys(res, doc["axes"][axis], notes)
    skeys = fitted_sensor(res, float(sensor.get("range_max", 10.0)))
    if sensor.get("kind") == "encoder" and "characteristic" in skeys:
        skeys.pop("characteristic")
        notes.append("characteristic not written: the template's sensor is an encoder-2 probe (linear)")
    sensor.update(skeys)
    comments = {f"axes.{axis}.kv": f"1/s (identified {res.drive['kv']:.4g} 1/s continuous; the same pole per cycle)"
                if res.drive["kv"] is not None else None,
                f"axes.{axis}.bus_delay_cycles": f"dead time {res.drive['dead_time'] * 1e3:.3g} ms"
                if res.drive["dead_time"] is not None else None,
                "sensor.delay_cycles": f"delay {res.sensor['delay'] * 1e3:.3g} ms" if res.sensor["delay"] is not None
                else None,
                **{f"axes.{axis}.{k}": c for k, c in limit_comments.items()}}
    path = out / name
    head = (f"# written by distctrl identify from {', '.join(Path(r['path']).name for r in res.recordings)}\n"
            "# keys not identified keep the template's values (or the defaults, docs/scenarios.md)\n")
    path.write_text(head + toml_text(doc, comments), encoding="utf-8")
    return path, notes


def plot_identification(res: Identification, path: str | os.PathLike) -> None:
    """:meth:`Identification.plot` saved to ``path`` (kept as a function: the report calls it)."""
    res.plot(path)


def write_report(res: Identification, out_dir: str | os.PathLike, scenario: str | None = None) -> Path:
    """``report.html`` (the figure embedded, the values with units, the fit quality, the warnings)
    and ``identify.png`` in ``out_dir``. The page: templates/identify_report.html.j2."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    png = out / "identify.png"
    plot_identification(res, png)
    j = result_json(res, scenario=scenario)
    rows = ([(f"drive.{k}", v, UNITS[k]) for k, v in j["drive"].items()]
            + [(f"sensor.{k}", v, UNITS[k]) for k, v in j["sensor"].items()])
    page = render("identify_report.html.j2", recordings=[r["path"] for r in res.recordings],
                  cycle_ms=f"{res.cycle_time * 1e3:g}", scenario=str(scenario or "-"), rows=rows,
                  summary=format_summary(res), warnings=list(res.warnings),
                  png=base64.b64encode(png.read_bytes()).decode("ascii"))
    page_path = out / "report.html"
    page_path.write_text(page, encoding="utf-8")
    return page_path
