"""``distctrl tune`` says the gain and phase margin of the tuned settings on the plant it tuned on
(issue 26): the same figures ``distctrl margins`` gives for the scenario with the tuned list, in the
text report and in --json."""
from __future__ import annotations

import json
import re
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

pytest.importorskip("numba")

from distctrl.params import parse_list_text  # noqa: E402
from distctrl.sim.scenario import load_scenario  # noqa: E402
from distctrl.cli.tune import tune_cmd  # noqa: E402
from distctrl.workbench.margins import analyse, loop_model, model_from_parts  # noqa: E402

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "tune_sheet.toml"

_cli = click.Group()
_cli.add_command(tune_cmd)


def _tune(tmp_path, *extra):
    r = CliRunner().invoke(_cli, ["tune", str(SCN), "--budget", "20", "--local", "--cycles", "1500",
                                  "--no-robustness", "--out", str(tmp_path / "t"), *extra])
    assert r.exit_code == 0, r.output
    return r


def test_tune_json_gives_the_margins_of_the_tuned_set_on_the_tuned_plant(tmp_path):
    obj = json.loads(_tune(tmp_path, "--json").stdout)
    st = obj["tuned"]["stability"]
    # what distctrl margins computes for this plant with the tuned list
    plant = loop_model(SCN)
    base = load_scenario(SCN).axes[plant.axis].params
    tuned = parse_list_text((tmp_path / "t" / "tuned.lis").read_text(), base=base).params
    expect = analyse(model_from_parts(tuned, plant.cycle_time, axis=plant.axis, mode=plant.mode, kv=plant.kv,
                                      feedforward=plant.feedforward, bus_delay_cycles=plant.bus_delay_cycles,
                                      sensor_delay_cycles=plant.sensor_delay_cycles,
                                      sensor_gain=plant.sensor_gain, resonance_hz=plant.resonance_hz,
                                      damping=plant.damping))
    assert st["stable"] is expect.stable
    assert st["gain_margin"] == pytest.approx(expect.gain_margin, rel=1e-6)
    assert st["phase_margin_deg"] == pytest.approx(expect.phase_margin_deg, rel=1e-6)
    assert st["gain_margin"] > 1.0 and st["phase_margin_deg"] > 0.0
    assert {"gain_margin_db", "phase_crossover_hz", "gain_crossover_hz", "kp_limit"} <= set(st)
    # and the scenario's own set, for comparison
    assert obj["scenario_params"]["stability"]["stable"] in (True, False)


def test_tune_text_report_says_the_margins(tmp_path):
    text = _tune(tmp_path).output
    assert re.search(r"gain margin [0-9.]+ \([+-][0-9.]+ dB\)", text), text
    assert re.search(r"phase margin -?[0-9.]+ deg", text), text
    assert "report.txt" in text and "gain margin" in (tmp_path / "t" / "report.txt").read_text()
