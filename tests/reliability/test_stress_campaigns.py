"""The resumable campaigns of ``make stress`` (issue 30) at small counts: they stop on a budget and
continue where they stopped with the same result as a run never stopped, record an escape and go on,
and the serve campaigns run against a real ``distctrl serve --ui`` with the page open."""
from __future__ import annotations

import json
import math
from types import SimpleNamespace

import pytest

from tests.scripts import load_script


def _load(name: str):
    return load_script(f"bench/{name}.py", f"distctrl_bench_{name}", beside=True)


soak = _load("soak")
stress = _load("stress")
stress_serve = _load("stress_serve")


def test_resumed_soak_is_the_soak_never_stopped(tmp_path):
    cycles, window = 30_000, 5_000
    whole = soak.soak_resumable(cycles, window, tmp_path / "a", None, checkpoint=5_000)
    part = soak.soak_resumable(cycles, window, tmp_path / "b", budget_s=0.0, checkpoint=5_000)
    assert not part["soak_complete"] and part["soak_stopped_by"] == "budget" and part["soak_cycles"] == window
    done = soak.soak_resumable(cycles, window, tmp_path / "b", None, checkpoint=5_000)
    assert done["soak_complete"] and done["soak_segments"] == 2 and done["soak_cycles"] == cycles
    assert whole["soak_pass"] and done["soak_pass"]
    # the same machine went on: every window's means are the uninterrupted run's
    assert done["soak_max_abs_window_mean_error_mm"] == whole["soak_max_abs_window_mean_error_mm"]
    assert done["soak_offset_drift_first_to_last_window_mm"] == whole["soak_offset_drift_first_to_last_window_mm"]
    with pytest.raises(SystemExit):                       # another target on the same state: refused
        soak.soak_resumable(2 * cycles, window, tmp_path / "b", None)


@pytest.mark.parametrize("suite", stress.TEXT_SUITES)
def test_text_campaign_stops_and_resumes_to_the_same_counts(tmp_path, suite):
    n = 120
    whole = stress.run_campaign(suite, n, None, tmp_path / "a", log=lambda *_: None)
    first = stress.run_campaign(suite, n, 0.0, tmp_path / "b", log=lambda *_: None)
    assert first["next"] == 1 and first["stopped_by"] == "budget"
    rest = stress.run_campaign(suite, n, None, tmp_path / "b", log=lambda *_: None)
    assert rest["next"] == n and rest["segments"] == 2
    assert rest["counts"] == whole["counts"] and rest["counts"]["inputs"] == n
    assert rest["escape_inputs"] == 0, rest["escapes"]
    # a second share of the inputs in its own file; the figures merge both
    stress.run_campaign(suite, n + 30, None, tmp_path / "b", log=lambda *_: None, start=n)
    fig = stress.write_figures(tmp_path / "b", tmp_path / "reliability.json")[suite]
    assert fig["inputs"] == n + 30 and fig["processes"] == 2 and fig["escapes"] == 0


def test_an_escape_is_recorded_with_its_input_and_the_campaign_goes_on(tmp_path, monkeypatch):
    real = stress.check

    def check(suite, item):
        if stress.make_input(suite, 3) == item:
            raise KeyError("boom")
        return real(suite, item)
    monkeypatch.setattr(stress, "check", check)
    st = stress.run_campaign("params", 10, None, tmp_path, log=lambda *_: None)
    assert st["next"] == 10 and st["escape_inputs"] == 1
    (sig, seen), = st["escapes"].items()
    assert sig.startswith("KeyError at ") and seen == {"count": 1, "first_input": 3, "inputs": [3]}
    text = (tmp_path / "escapes" / "params-3.txt").read_text()
    assert "KeyError: 'boom'" in text and repr(stress.make_input("params", 3)) in text


def _machine(offset: float, command: float, max_dev: float = 1.0, sw=(0.0, 100.0)):
    params = SimpleNamespace(max_deviation=max_dev, check_sw_limit_switch=True, sw_limit_min=sw[0],
                             sw_limit_max=sw[1])
    out = SimpleNamespace(offset=offset, command_position=command)
    return SimpleNamespace(outputs={"Z": out}, controllers={"Z": SimpleNamespace(params=params)}, dc_axes=["Z"])


@pytest.mark.parametrize("offset, command, kind", [(math.nan, 50.0, "nonfinite"), (0.5, math.inf, "nonfinite"),
                                                   (1.5, 51.5, "bound"), (0.9, 100.5, "bound")])
def test_the_per_cycle_bounds_catch_nan_and_overruns(offset, command, kind):
    with pytest.raises(stress.Escape) as info:
        stress.Bounds()(_machine(offset, command), 7)
    assert info.value.kind == kind


def test_the_per_cycle_bounds_pass_a_programmed_position_outside_the_limits():
    stress.Bounds()(_machine(0.5, 120.5), 1)        # the NC program's own position: not the offset's doing
    stress.Bounds()(_machine(-0.5, 50.0), 1)


def test_framing_model_port_close_closes():
    P = stress_serve.P
    close = P.AMS_TCP_HEADER.pack(P.AMS_TCP_PORT_CLOSE, 2) + b"\0\0"
    read = P.read_request(0x4020, 0, 4, invoke_id=9)
    assert stress_serve.predict(read + close + read) == ([9], "closed")
    assert stress_serve.predict(read + read[:10]) == ([9], "open")


def test_serve_campaigns_against_a_served_machine_with_the_page_open(tmp_path, monkeypatch):
    """A thousand hostile ADS frames (the page open in Chromium) and a hundred hostile page requests
    against ``python -m distctrl serve --ui``, with health checks: no escape, serve ends cleanly."""
    monkeypatch.setattr(stress_serve, "HEALTH_EVERY", 20)
    ads = stress_serve.run_campaign("ads", 1_000, None, tmp_path, log=print)["figures"]
    assert ads["escapes"] == 0, ads["escape_kinds"]
    assert ads["counts"]["frames"] >= 1_000 and ads["health_checks"] >= 2
    assert ads["serve_stops"] == [{"returncode": 0, "traceback": False, "refused_logged": ads["serve_stops"][0]["refused_logged"]}]
    page = stress_serve.run_campaign("page", 100, None, tmp_path, log=print, page_open=False)["figures"]
    assert page["escapes"] == 0, page["escape_kinds"]
    assert page["inputs"] == 100 and page["health_checks"] >= 2
    assert page["serve_stops"][0]["returncode"] == 0 and not page["serve_stops"][0]["traceback"]
    saved = json.loads((tmp_path / "ads.json").read_text())
    assert saved["figures"]["threads_left"] == 0
