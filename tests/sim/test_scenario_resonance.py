"""Scenario keys ``resonance_hz`` / ``damping`` and what the virtual machine does with the nozzle."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from distctrl.sim.machine import Machine
from distctrl.sim.runner import load_program, run
from distctrl.sim.scenario import AXIS_KEYS, ScenarioError, load_scenario, scenario_from_dict

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "scenarios"


def _sc(z: dict, cycle_time=0.001, **top):
    cfg = {"program_text": "N10 G1 Z1 F600\nN20 M30\n", "cycle_time": cycle_time, "axes": {"Z": z},
           "sensor": {"axis": "Z", "kind": "encoder"}}
    cfg.update(top)
    return scenario_from_dict(cfg)


def test_keys_defaults_and_drive():
    assert {"resonance_hz", "damping"} <= set(AXIS_KEYS)
    ax = _sc({}).axes["Z"]
    assert (ax.resonance_hz, ax.damping) == (0.0, 0.05)
    ax = _sc({"resonance_hz": 40, "damping": 0.1}).axes["Z"]
    d = ax.make_drive(0.001)
    assert (d.resonance_hz, d.damping) == (40.0, 0.1) and d.resonance_phi is not None
    assert _sc({"resonance_hz": 500.0}, cycle_time=0.0005).axes["Z"].resonance_hz == 500.0   # 1/(4T)


@pytest.mark.parametrize("z,key,allowed", [
    ({"resonance_hz": 251.0}, "axes.Z.resonance_hz", "[0, 250] Hz"),
    ({"resonance_hz": -3.0}, "axes.Z.resonance_hz", "[0, 250] Hz"),
    ({"resonance_hz": "40"}, "axes.Z.resonance_hz", "[0, 250] Hz"),
    ({"resonance_hz": 40.0, "damping": 0.0}, "axes.Z.damping", "(0, 1]"),
    ({"resonance_hz": 40.0, "damping": 2.0}, "axes.Z.damping", "(0, 1]"),
])
def test_invalid_values_name_the_key_and_the_allowed_range(z, key, allowed):
    with pytest.raises(ScenarioError) as exc:
        _sc(z)
    msg = str(exc.value)
    assert key in msg and allowed in msg


def test_the_range_follows_the_cycle_time():
    with pytest.raises(ScenarioError, match=r"\[0, 125\] Hz.*cycle_time = 0.002"):
        _sc({"resonance_hz": 130.0}, cycle_time=0.002)


def test_sensor_and_true_distance_see_the_nozzle_the_encoder_the_motor():
    sc = load_scenario(EXAMPLES / "resonant_z.toml")
    m = Machine(sc, load_program(sc))
    z = m.drives["Z"]
    seen = []
    for _ in range(1500):
        nozzle, motor = z.nozzle, z.position        # the sensor reads before the drives step
        m.step()
        seen.append((m.true_distance, nozzle - m.true_surface, nozzle - motor,
                     m.inputs["Z"].actual_position, z.actual))
    arr = np.array(seen)
    np.testing.assert_array_equal(arr[:, 0], arr[:, 1])       # true distance (collision check) = nozzle
    assert np.max(np.abs(arr[:, 2])) > 0.01                   # the nozzle really deflects
    # the controller is fed the motor encoder of the previous cycle
    np.testing.assert_array_equal(arr[1:, 3], arr[:-1, 4])


def test_explicit_zero_resonance_runs_like_no_key():
    base = load_scenario(EXAMPLES / "tune_sheet.toml")
    text = (EXAMPLES / "tune_sheet.toml").read_text().replace("a_max = 20000.0",
                                                              "a_max = 20000.0\nresonance_hz = 0\ndamping = 0.3")
    from distctrl.sim.scenario import scenario_from_text

    zero = scenario_from_text(text, base_dir=EXAMPLES)
    assert zero.axes["Z"].resonance_hz == 0.0
    a, b = run(base), run(zero)
    np.testing.assert_array_equal(a.trace.data, b.trace.data)
    assert a.trace.columns == b.trace.columns


def test_the_trace_has_the_nozzle_of_a_resonant_axis_only():
    r = run(load_scenario(EXAMPLES / "resonant_z.toml"))
    tr = r.trace
    assert "Z.nozzle" in tr.columns and "X.nozzle" not in tr.columns and tr.units["Z.nozzle"] == "mm"
    # a row holds the positions after the cycle's drive step; the sensor read before it
    np.testing.assert_array_equal(tr["Z.nozzle"][:-1] - tr["true.surface"][1:], tr["true.distance"][1:])
    assert np.max(np.abs(tr["Z.nozzle"] - tr["Z.act"])) > 0.01
    assert "Z.nozzle" not in run(load_scenario(EXAMPLES / "tune_sheet.toml")).trace.columns
