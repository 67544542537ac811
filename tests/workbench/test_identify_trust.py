"""identify says when the data cannot give an answer (issue 39, audit new-user-2026-12-07 M5):

* a distctrl trace recorded with distance control on (its ``Z.dc.state`` column) is refused, one line,
  exit 1, with what to record instead; ``--out`` writes nothing;
* the same recording without the state column (a plain CSV) fails the open-loop check from the data
  itself: what the sensor path's model leaves over is a slow signal, not noise. The sensor path's
  figures are withheld (null, never a noise of 867 um "± 11 um"), the warning comes first, exit 4 and
  ``--out`` writes nothing;
* every warning the text prints is in the JSON's ``warnings`` too, on every warning path.

The recordings of distance control come from ``distctrl run`` (the simulator, SET_POS over a sine
surface: examples/scenarios/dist_1.toml); the open-loop ones from tests/workbench/hidden_plants.py.
"""
from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from distctrl.cli import main
from tests.workbench import hidden_plants

ROOT = Path(__file__).resolve().parents[2]
COLS = ["--command", "Z.cmd", "--actual", "Z.act", "--sensor", "Z.dc.sensor"]
CSV_COLS = ["--command", "set_pos", "--actual", "act_pos", "--sensor", "sensor"]


def _cli(args):
    return CliRunner().invoke(main, args, catch_exceptions=False)


@pytest.fixture(scope="module")
def closed_loop(tmp_path_factory):
    """A run trace of dist_1.toml (distance control ACTIVE most of the time) and the same signals as a
    plain CSV without the state column."""
    d = tmp_path_factory.mktemp("closed")
    trace = d / "t.parquet"
    r = _cli(["run", str(ROOT / "examples" / "scenarios" / "dist_1.toml"), "--trace", str(trace)])
    assert r.exit_code == 0, r.output
    from distctrl.trace import load_trace

    tr = load_trace(trace)
    cols = list(tr.columns)
    state = tr.data[:, cols.index("Z.dc.state")]
    assert np.count_nonzero(state == 1) > 1000
    data = tr.data[:, [cols.index(k) for k in ("t", "Z.cmd", "Z.act", "Z.dc.sensor")]]
    csv = d / "closed.csv"
    np.savetxt(csv, data, delimiter=",", header="time,set_pos,act_pos,sensor", comments="", fmt="%.9g")
    return trace, csv


def test_a_trace_recorded_with_distance_control_on_is_refused(closed_loop, tmp_path):
    """Before: noise 867 um ± 11 um, exit 0, no warning (M5)."""
    trace, _ = closed_loop
    out = tmp_path / "fitted"
    r = _cli(["identify", str(trace), *COLS, "--out", str(out)])
    assert r.exit_code == 1, r.output
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), r.output
    assert "distance control was closing the loop" in lines[0] and "Z.dc.state" in lines[0]
    assert "record with distance control off, above a flat sheet" in lines[0]
    assert not out.exists()
    r = _cli(["identify", str(trace), *COLS, "--json"])
    assert r.exit_code == 1
    obj = json.loads(r.stdout)
    assert obj["outcome"] == "error" and obj["exit_code"] == 1 and "distance control" in obj["error"]


def test_closed_loop_without_a_state_column_fails_the_open_loop_check(closed_loop, tmp_path):
    """The command follows the sensor: what the model leaves over is the surface, not noise."""
    _, csv = closed_loop
    out = tmp_path / "fitted"
    r = _cli(["identify", str(csv), *CSV_COLS, "--json", "--out", str(out)])
    assert r.exit_code == 4, r.output
    obj = json.loads(r.stdout)
    assert obj["warnings"][0].startswith("open-loop check failed")
    assert "record with distance control off, above a flat sheet" in obj["warnings"][0]
    assert obj["details"]["open_loop"]["passed"] is False
    assert obj["details"]["open_loop"]["residual_lag1"] > 0.9
    assert obj["sensor"] == {"delay": None, "noise_std": None, "characteristic": None}
    assert obj["drive"]["resonance_hz"] is None and obj["drive"]["damping"] is None
    assert obj["uncertainty"]["sensor"]["noise_std"] is None
    assert obj["drive"]["kv"] is not None                  # command -> motor stands in a closed loop too
    assert obj["scenario"] is None and not out.exists()
    r = _cli(["identify", str(csv), *CSV_COLS])
    assert r.exit_code == 4
    assert r.stderr.splitlines()[0].startswith("warning: open-loop check failed")
    assert "noise std     -" in r.stdout


@pytest.fixture(scope="module")
def hidden_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("hidden")
    plant = hidden_plants.random_plant(3)
    paths, _ = hidden_plants.write_recordings(plant, 3, d, seconds=6.0, n_big=1)
    return plant, {p.stem.split("_", 1)[1]: str(p) for p in paths}


def test_open_loop_recordings_pass_the_check(hidden_files):
    _, files = hidden_files
    r = _cli(["identify", *files.values(), *CSV_COLS, "--json"])
    assert r.exit_code == 0, r.output
    obj = json.loads(r.stdout)
    assert obj["details"]["open_loop"]["passed"] is True
    assert abs(obj["details"]["open_loop"]["residual_lag1"]) < 0.2


# every warning path: (recordings, extra options); each prints warnings (checked), and the JSON must carry
# exactly the same ones, in the same order
WARNING_CASES = {
    "ramp alone: kv, dead time, resonance, characteristic's zero": (["ramp"], []),
    "steps alone, no --surface": (["steps"], []),
    "chirp alone: the limits as lower bounds": (["chirp"], []),
    "--out notes (the limits' bounds in fitted.toml)": (["chirp", "ramp"], ["--out", "{tmp}/fitted"]),
    "--calibrated-at never read": (["steps", "ramp"], ["--calibrated-at", "900"]),
    "closed loop": (["closed"], []),
}


@pytest.mark.parametrize("case", list(WARNING_CASES))
def test_every_warning_the_text_prints_is_in_the_json(case, hidden_files, closed_loop, tmp_path):
    names, extra = WARNING_CASES[case]
    _, files = hidden_files
    paths = [str(closed_loop[1]) if n == "closed" else files[n] for n in names]
    extra = [e.replace("{tmp}", str(tmp_path)) for e in extra]
    text = _cli(["identify", *paths, *CSV_COLS, *extra])
    printed = [ln[len("warning: "):] for ln in text.stderr.splitlines() if ln.startswith("warning: ")]
    assert printed, text.output
    extra_json = [e.replace(str(tmp_path), str(tmp_path / "j")) for e in extra]
    js = _cli(["identify", *paths, *CSV_COLS, *extra_json, "--json"])
    assert js.exit_code == text.exit_code
    obj = json.loads(js.stdout)
    assert [w.replace(str(tmp_path / "j"), str(tmp_path)) for w in obj["warnings"]] == printed


def test_every_warning_identify_raises_is_in_its_result(hidden_files, closed_loop):
    """From Python: each IdentifyWarning raised is in ``Identification.warnings`` (and so in to_dict())."""
    from distctrl.workbench.identify import IdentifyWarning, identify, load_signals

    _, files = hidden_files
    for paths in ([files["ramp"]], [files["chirp"]], [str(closed_loop[1])]):
        sigs = [load_signals(p, command="set_pos", actual="act_pos", sensor="sensor") for p in paths]
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            res = identify(sigs)
        raised = [str(w.message) for w in seen if issubclass(w.category, IdentifyWarning)]
        assert raised and sorted(raised) == sorted(res.warnings) == sorted(res.to_dict()["warnings"])
