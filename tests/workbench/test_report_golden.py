"""The HTML pages of distctrl.workbench (the run report, the trace report, the identify report) pinned
byte for byte against stored pages (tests/workbench/data/*.html).

These tests make sure a change of a builder (or of its templates) changes the page only on purpose. The plots are replaced by fixed bytes (their
pixels depend on the matplotlib version, and test_report.py checks them); everything else is the
real builder: every section, table, badge, note, the escaping of quotes and markup, the NC program
listing with its hit lines. Paths under the repository are written as ``<ROOT>``.

After an intended change of a page, regenerate the stored pages with
``DISTCTRL_REGOLD=1 python -m pytest tests/workbench/test_report_golden.py`` and review the diff.
"""
from __future__ import annotations

import datetime as dt
import os
from pathlib import Path
from types import SimpleNamespace

from distctrl.sim.runner import RunResult
from distctrl.sim.scenario import scenario_from_text
from distctrl.workbench import report
from distctrl.workbench.identify import output as identify_output
from distctrl.workbench.identify.fit import Identification

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(__file__).resolve().parent / "data"
SCENARIOS = ROOT / "examples" / "scenarios"
NOW = dt.datetime(2026, 11, 26, 14, 0, 0, tzinfo=dt.timezone.utc)
REGOLD = os.environ.get("DISTCTRL_REGOLD") == "1"

#: every part of the scenario section: quotes and markup in names, V.E. variables, an axis list with
#: changed values, a channel list, surface features, sensor faults, events, a program with a hit line
SCENARIO = '''
name = "golden <report> & 'quotes' \\"double\\""
program_text = """
N10 G90 G0 X0 Z31 ; <start> & 'go'
N20 Z[DIST_CTRL ON CONST_DIST SET_DIST=1]
N30 G1 X10 F3000
N40 M30
"""
duration = 0.5
seed = 7
[variables]
SENSOR = 1.5
[channel]
params = "../channel_3d_12_8_3.lis"
kinematics = "none"
[axes.X]
v_max = 250.0
[axes.Z]
params = "z_probe.lis"
start = 31.0
kv = 35.0
[surface]
base = 30.0
features = [
  { type = "step", axis = "X", at = 5.0, height = 0.5 },
  { type = "ramp", axis = "X", start = 6.0, end = 8.0, height = 0.25 },
]
[sensor]
axis = "Z"
kind = "distance"
variable = "SENSOR"
faults = [ { kind = "jump", value = 0.2, start_time = 0.1, duration = 0.05 } ]
[[events]]
t = 0.2
variable = { name = "SENSOR", value = 2.0 }
[[events]]
t = 0.1
override = { value = 0.5 }
'''

_PNG = b"\x89PNG\r\n\x1a\n-golden-"


def _fake_plots(monkeypatch):
    monkeypatch.setattr(report, "_timeline_png", lambda trace, events, t_end: _PNG + b"timeline")
    monkeypatch.setattr(report, "_scope_png", lambda trace, title, events: _PNG + b"scope")
    monkeypatch.setattr(report, "_zoom_png", lambda trace, title, events: (_PNG + b"zoom", "zoom <caption> & 'x'"))


def _check(page: Path, name: str) -> None:
    text = page.read_text(encoding="utf-8").replace(str(ROOT), "<ROOT>")
    stored = DATA / name
    if REGOLD:
        stored.write_text(text, encoding="utf-8")
    expected = stored.read_text(encoding="utf-8")
    assert text == expected, f"{name}: the page differs from the stored one (see the module docstring)"


def _result(**kw) -> RunResult:
    base = dict(
        name="golden <run> & 'q'", completed=False, aborted=True,
        errors=[{"id": 70335, "line": 2, "t": 0.012, "message": "DIST_CTRL ON without <SET_POS> & 'x'"}],
        warnings=[{"id": 900030, "line": 3, "t": 0.0105, "message": 'collision "deep"'},
                  {"id": 70400, "line": None, "t": 0.3, "message": "no line"}],
        final_state="ERROR", cycles=500, cycle_time=0.001,
        metrics={"distance_error_rms": 0.0123456789, "distance_error_max": None, "settle_time": float("nan"),
                 "collisions": 2, "oscillation_frequency_hz": 12.5, "tracking_cycles": 321, "custom_mm": 1.0,
                 "custom_thing": True},
        trace=SimpleNamespace(rows=3), trace_path="/nonexistent/<trace>.csv",
        notes=["a note with <markup> & 'quotes'"], outcome="aborted")
    base.update(kw)
    return RunResult(**base)


def _scenario():
    return scenario_from_text(SCENARIO, base_dir=SCENARIOS, source=str(SCENARIOS / "golden.toml"))


def test_run_report_with_errors_warnings_and_everything(monkeypatch, tmp_path):
    _fake_plots(monkeypatch)
    page = report.write_report(_result(), _scenario(), tmp_path, now=NOW)
    _check(page, "report_full.html")


def test_run_report_completed_without_events_or_plots(monkeypatch, tmp_path):
    _fake_plots(monkeypatch)
    sc = scenario_from_text('name = "plain"\nprogram_text = "N10 G1 X1 F100\\nN20 M30\\n"\n[axes.X]\n',
                            base_dir=SCENARIOS, source="plain.toml")
    res = _result(name="plain", completed=True, aborted=False, errors=[], warnings=[], final_state="OFF",
                  metrics={"distance_error_rms": None}, trace=None, trace_path=None, notes=[],
                  outcome="completed")
    page = report.write_report(res, sc, tmp_path, title="Title <&> 'x'", now=NOW)
    _check(page, "report_plain.html")


def test_run_report_interrupted_with_no_zoom(monkeypatch, tmp_path):
    _fake_plots(monkeypatch)
    monkeypatch.setattr(report, "_zoom_png", lambda trace, title, events: None)
    res = _result(interrupted=True, completed=False, aborted=False, errors=[], outcome="interrupted",
                  metrics={})
    page = report.write_report(res, _scenario(), tmp_path, now=NOW)
    _check(page, "report_interrupted.html")


def test_trace_report(monkeypatch, tmp_path):
    _fake_plots(monkeypatch)
    csv = tmp_path / "golden.csv"
    csv.write_text("t,Z.dc.state,Z.act,Z.dc.dist_wanted,true.distance\n"
                   "0.000,0,31.0,1.0,1.0\n0.001,2,31.0,1.0,1.01\n0.002,2,30.99,1.0,0.98\n", encoding="utf-8")
    errors = {"errors": [{"id": 70335, "line": 2, "t": 0.001, "message": "<e> & 'q'"}], "warnings": []}
    page = report.report_from_trace(csv, tmp_path / "html", errors=errors, title="trace 'golden' <&>", now=NOW)
    text = page.read_text(encoding="utf-8").replace(str(tmp_path), "<TMP>")
    page.write_text(text, encoding="utf-8")
    _check(page, "report_trace.html")


def test_identify_report(monkeypatch, tmp_path):
    monkeypatch.setattr(identify_output, "plot_identification", lambda res, path: Path(path).write_bytes(_PNG))
    res = Identification(
        cycle_time=0.001,
        drive={"kv": 40.1234, "dead_time": 0.003, "v_max": None, "a_max": 5000.0, "resonance_hz": None,
               "damping": None},
        sensor={"delay": 0.002, "noise_std": 0.004, "characteristic": [[1.0, 1.01], [2.0, 2.03]]},
        fit={"drive_fit_percent": [97.5], "drive_rms_mm": [0.001], "sensor_rms_mm": [0.002]},
        extra={"sensor_reads": "distance <mm> & 'x'"},
        warnings=["no resonance: <none> & 'found'"],
        recordings=[{"path": "/rec/a <1>.csv"}, {"path": "/rec/b&'2'.csv"}])
    page = identify_output.write_report(res, tmp_path, scenario="/out/fitted 'x' <y>.toml")
    _check(page, "identify_report.html")


def test_identify_report_without_warnings(monkeypatch, tmp_path):
    monkeypatch.setattr(identify_output, "plot_identification", lambda res, path: Path(path).write_bytes(_PNG))
    res = Identification(
        cycle_time=0.002,
        drive={k: None for k in ("kv", "dead_time", "v_max", "a_max", "resonance_hz", "damping")},
        sensor={"delay": None, "noise_std": None, "characteristic": None},
        recordings=[{"path": "r.csv"}])
    page = identify_output.write_report(res, tmp_path)
    _check(page, "identify_report_plain.html")


def test_run_report_time_limit_with_parameter_warnings(monkeypatch, tmp_path):
    _fake_plots(monkeypatch)
    sc = _scenario()
    object.__setattr__(sc.axes["Z"], "params_warnings", ["kenngr.x <unknown> & 'ignored'", "second"])
    res = _result(completed=False, aborted=False, errors=[], outcome="time_limit", time_limit=0.5,
                  metrics={"collisions": 1})
    page = report.write_report(res, sc, tmp_path, now=NOW)
    _check(page, "report_time_limit.html")
