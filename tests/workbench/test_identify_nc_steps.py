"""identify on recordings made as docs/identify.md says, with the NC moving the axis (new-user audit M2):
G0 steps of 0.2-0.5 mm that the interpolator shapes with the axis's a_max give kv and the dead time
from the command's own shape, whatever a_max; v_max and a_max of the drive cannot be seen when the NC
limits the command below them, which is said plainly, and fitted.toml carries the values the command
reached as lower bounds instead of silently taking the defaults (audit R7)."""
from __future__ import annotations

import json
import math
import tomllib

import pytest
from click.testing import CliRunner

from distctrl.cli import main
from tests.workbench.identify_nc import record

ARGS = ["--command", "Z.cmd", "--actual", "Z.act", "--sensor", "Z.dc.sensor", "--surface", "30"]
T = 0.001


def kv_continuous(kv_sim: float) -> float:
    """The continuous kv of the simulator's per-cycle drive x += kv (c - x) T (docs/identify.md)."""
    return -math.log1p(-kv_sim * T) / T


def identify(paths, *extra):
    r = CliRunner().invoke(main, ["identify", *map(str, paths), *ARGS, "--json", *map(str, extra)],
                           catch_exceptions=False)
    assert r.exit_code == 0, r.output
    return json.loads(r.stdout)


@pytest.fixture(scope="module")
def rec(tmp_path_factory):
    d = tmp_path_factory.mktemp("nc_steps")
    cache = {}

    def get(kind="steps", **plant):
        key = (kind, tuple(sorted(plant.items())))
        if key not in cache:
            cache[key] = record(d, kind, **plant)
        return cache[key]
    return get


@pytest.mark.parametrize("a_max, kv", [(2000.0, 45.0), (5000.0, 45.0), (10000.0, 45.0), (5000.0, 25.0),
                                       (5000.0, 80.0)])
def test_nc_interpolated_steps_give_kv_and_the_dead_time(rec, a_max, kv):
    js = identify([rec(a_max=a_max, kv=kv)])
    d = js["drive"]
    assert d["kv"] is not None and d["dead_time"] is not None, js["warnings"]
    assert d["kv"] == pytest.approx(kv_continuous(kv), rel=0.01)
    assert d["dead_time"] == pytest.approx(0.003, abs=0.00025)
    assert not [w for w in js["warnings"] if w.startswith("kv and dead time")]


def test_limits_below_the_ncs_are_named_as_lower_bounds_not_asked_for_with_larger_steps(rec):
    js = identify([rec(a_max=5000.0)])
    d, w = js["drive"], " ".join(js["warnings"])
    assert d["v_max"] is None and d["a_max"] is None          # the drive never saturated: not identified
    assert "large enough" not in w and "steps of 1-2 mm" not in w, w
    assert "the command never exceeded v = 80" in w and "a = 5000 mm/s^2" in w, w
    assert "at least these" in w
    det = js["details"]
    assert det["v_max_lower_bound"] == pytest.approx(80.0, rel=0.01)
    assert det["a_max_lower_bound"] == pytest.approx(5000.0, rel=0.01)


def test_fitted_toml_carries_the_lower_bounds_and_says_so(rec, tmp_path):
    identify([rec(a_max=5000.0)], "--out", tmp_path / "fit")
    text = (tmp_path / "fit" / "fitted.toml").read_text()
    z = tomllib.loads(text)["axes"]["Z"]
    assert z["v_max"] == pytest.approx(80.0, rel=0.01) and z["a_max"] == pytest.approx(5000.0, rel=0.01)
    lines = {ln.split("=")[0].strip(): ln for ln in text.splitlines() if "=" in ln}
    assert "lower bound" in lines["v_max"] and "lower bound" in lines["a_max"], text


def test_a_templates_configured_limits_are_kept_and_named(rec, tmp_path):
    tpl = tmp_path / "tpl.toml"
    tpl.write_text('program_text = "M30\\n"\n[axes.Z]\nv_max = 90.0\na_max = 6000.0\n'
                   '[sensor]\naxis = "Z"\nkind = "distance"\nvariable = "SENSOR"\n', encoding="utf-8")
    identify([rec(a_max=5000.0)], "--out", tmp_path / "fit", "--template", tpl)
    text = (tmp_path / "fit" / "fitted.toml").read_text()
    z = tomllib.loads(text)["axes"]["Z"]
    assert z["v_max"] == 90.0 and z["a_max"] == 6000.0
    lines = {ln.split("=")[0].strip(): ln for ln in text.splitlines() if "=" in ln}
    assert "configured" in lines["v_max"] and "configured" in lines["a_max"], text


def test_a_slow_ramp_alone_still_does_not_give_kv(rec):
    js = identify([rec("ramp", a_max=5000.0)])
    assert js["drive"]["kv"] is None and js["drive"]["dead_time"] is None
    assert any(w.startswith("kv and dead time") for w in js["warnings"])


def test_steps_and_a_ramp_together_give_kv_as_the_steps_alone(rec):
    """The audit's command: ``identify steps.csv ramp.csv``. The simulated ramp explains itself to 1e-14 mm
    at any dead time; its residuals must not set the noise scale of the steps' (which made every step
    sample an outlier and the dead time's cost flat)."""
    js = identify([rec(a_max=5000.0), rec("ramp", a_max=5000.0)])
    d = js["drive"]
    assert d["kv"] == pytest.approx(kv_continuous(45.0), rel=0.01), js["warnings"]
    assert d["dead_time"] == pytest.approx(0.003, abs=0.00025)
