"""The phase margin of ``distctrl margins`` and of tune's margin constraint is the distance to -1 at every
gain crossover (new-user audit M2, issue 39), for ``analyse`` (distctrl/workbench/margins/analysis.py)
and for :class:`distctrl.tuning.robust.MarginConstraint`.

A 0 dB crossing at 1 at +4 deg (a resonance carries the phase round to -356 deg) is 176 deg away from -1;
``(angle mod 360) - 180`` called it a -176 deg margin and named it the binding constraint.

The reference is independent of the code under test: python-control's crossings
(``control.stability_margins(..., returnall=True)`` of the loop as one polynomial transfer function)
and, at each, the angle between L and -1 as ``acos(-Re L)`` (no phase wrapping at all). python-control's
own PM figure is ``(angle mod 360) - 180`` too (0.10.2, control/margins.py): the distance equals it where
the crossing lies in the lower half-plane and its absolute value in the upper one, which is checked.
The loops come from a random generator over drives, delays, resonances, filters and gains.
"""
from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from distctrl.base.kinds import FilterType
from distctrl.params import load_list
from distctrl.params.axis import AxisParameters
from distctrl.tuning.robust import MarginConstraint, PlantAllowance
from distctrl.workbench.margins import analyse, model_from_parts

T = 0.001
#: the plant tuned on only (no variants): the constraint's nominal figures
NO_ALLOWANCE = PlantAllowance(kv=0.0, resonance=0.0, damping=1.0, dead_cycles=0)


def _random_loop(rng: np.random.Generator):
    """A resonant loop: drive kv, bus and sensor delays, a mode from 15 to 200 Hz with zeta 0.01-0.3,
    KP log-uniform, a PD or PI part, and one of the filters."""
    ft = [FilterType.DEFAULT, FilterType.MOVING_AVERAGE, FilterType.EXPO_MEAN][int(rng.integers(0, 3))]
    p = AxisParameters().replace(
        kp=float(np.exp(rng.uniform(math.log(0.01), math.log(0.6)))),
        i_tn=float(rng.choice([0.0, rng.uniform(0.05, 1.0)])),
        d_tv=float(rng.choice([0.0, rng.uniform(0.0005, 0.01)])),
        filter_type=ft, n_cycles=int(rng.integers(1, 12)), smoothing_factor=float(rng.uniform(0.1, 0.9)),
        use_both_encoders=bool(rng.integers(0, 2)))
    f0 = float(np.exp(rng.uniform(math.log(15.0), math.log(200.0))))
    zeta = float(np.exp(rng.uniform(math.log(0.01), math.log(0.3))))
    model = model_from_parts(p, T, kv=float(rng.uniform(20.0, 120.0)),
                             bus_delay_cycles=int(rng.integers(1, 4)),
                             sensor_delay_cycles=int(rng.integers(0, 5)),
                             sensor_gain=float(rng.uniform(0.9, 1.1)),
                             resonance_hz=f0, damping=zeta)
    return p, model


def _python_control_crossings(model) -> list[tuple[float, float]]:
    """(frequency in Hz, python-control's PM in deg) of every gain crossover python-control reports that
    the loop's response confirms (|L| = 1 to 1e-6, between 0 and the Nyquist frequency)."""
    import control

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        _, pms, _, _, wcs, _ = control.stability_margins(model.loop(), returnall=True)
    out = []
    for pm, w in zip(np.atleast_1d(pms), np.atleast_1d(wcs)):
        if not (math.isfinite(w) and 0.0 < w < math.pi / T):
            continue
        if abs(abs(complex(model.response(np.array([w]))[0])) - 1.0) <= 1e-6:
            out.append((float(w) / (2.0 * math.pi), float(pm)))
    return out


def _distance_deg(model, f_hz: float) -> tuple[float, complex]:
    L = complex(model.response(np.array([2.0 * math.pi * f_hz]))[0])
    return math.degrees(math.acos(max(-1.0, min(1.0, -L.real / abs(L))))), L


N_LOOPS = 60


def test_margins_phase_margin_is_the_distance_to_minus_one_at_every_crossing():
    rng = np.random.default_rng(3901)
    checked = upper = 0
    for case in range(N_LOOPS):
        _, model = _random_loop(rng)
        r = analyse(model)
        ours = list(r.phase_margins)
        for pm, f in ours:
            d, _ = _distance_deg(model, f)
            assert pm == pytest.approx(d, abs=1e-6), (case, f, pm, d)
            assert pm >= 0.0
        if ours:
            assert r.phase_margin_deg == pytest.approx(min(pm for pm, _ in ours), abs=1e-9)
        for f, pm_pc in _python_control_crossings(model):
            match = [pm for pm, fo in ours if math.isclose(fo, f, rel_tol=1e-5)]
            assert match, (case, f, ours)
            d, L = _distance_deg(model, f)
            # python-control's crossing frequency from its polynomial method agrees to ~1e-6
            assert match[0] == pytest.approx(abs(pm_pc), abs=0.01)
            assert abs(pm_pc) == pytest.approx(d, abs=0.01)
            if L.imag > 0.0:
                upper += 1
                assert pm_pc < 0.0              # python-control's figure: (angle mod 360) - 180
            else:
                assert match[0] == pytest.approx(pm_pc, abs=0.01)
            checked += 1
    print(f"{checked} crossings of {N_LOOPS} random resonant loops checked, {upper} in the upper half-plane")
    assert checked >= N_LOOPS // 2 and upper >= 5


def _reference_crossings(model) -> list[tuple[float, float]]:
    """(distance to -1 in deg, Hz) at every 0 dB crossing of the loop's factor-by-factor response
    (LoopModel.response) on a linear 0.005 Hz grid, each refined by bisection on |L| = 1."""
    f = np.arange(0.05, 0.5 / T, 0.005)
    lm = np.log(np.abs(model.response(2.0 * math.pi * f)))
    out = []
    for k in np.nonzero(np.signbit(lm[:-1]) != np.signbit(lm[1:]))[0]:
        a, b = f[k], f[k + 1]
        for _ in range(50):
            m = 0.5 * (a + b)
            lmid = math.log(abs(complex(model.response(np.array([2.0 * math.pi * m]))[0])))
            if math.copysign(1.0, lmid) == math.copysign(1.0, lm[k]):
                a = m
            else:
                b = m
        out.append((_distance_deg(model, 0.5 * (a + b))[0], 0.5 * (a + b)))
    return out


def test_tune_constraint_phase_margin_is_the_distance_to_minus_one():
    """The constraint's nominal phase margin is the smallest distance to -1 over the crossings of the
    loop's response (its grid interpolates: 0.5 deg), never negative, also where the crossing lies in the
    upper half-plane."""
    rng = np.random.default_rng(3902)
    upper = checked = 0
    for case in range(N_LOOPS):
        p, model = _random_loop(rng)
        ref = _reference_crossings(model)
        chk = MarginConstraint(model, allowance=NO_ALLOWANCE).check(p)
        if not ref:
            assert chk.nominal_phase_margin_deg is None
            continue
        assert chk.phase_margin_deg >= 0.0
        assert chk.nominal_phase_margin_deg == pytest.approx(min(d for d, _ in ref), abs=0.5), (case, ref)
        upper += sum(_distance_deg(model, f)[1].imag > 0.0 for _, f in ref)
        checked += 1
    print(f"{checked} of {N_LOOPS} random resonant loops with a crossing; {upper} crossings in the upper "
          "half-plane")
    assert checked >= N_LOOPS // 2 and upper >= 5


def _audit_plant():
    """The audit's commissioning plant (new-user audit M2): z_laser.lis, kv 60, a 52 Hz mode with zeta 0.06,
    the probe 3 cycles late."""
    lis = Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "z_laser.lis"
    p = load_list(lis)
    p = getattr(p, "params", p)
    return p, model_from_parts(p, T, kv=60.0, bus_delay_cycles=1, sensor_delay_cycles=3, resonance_hz=52.0,
                               damping=0.06)


def test_the_audits_crossing_at_plus_4_deg_is_176_deg_from_minus_one_and_not_binding():
    p, model = _audit_plant()
    r = analyse(model)
    at_peak = [(pm, f) for pm, f in r.phase_margins if 49.0 < f < 51.0]
    assert len(at_peak) == 1
    pm, f = at_peak[0]
    d, L = _distance_deg(model, f)
    assert L.imag > 0.0 and 170.0 < pm < 180.0 and pm == pytest.approx(d, abs=1e-6)
    assert r.phase_margin_deg == pytest.approx(44.35, abs=0.1)        # the crossing at 41.7 Hz
    c = MarginConstraint(model)
    chk = c.check(p)
    assert not chk.ok and chk.gain_margin < 2.0
    # the worst phase margin is where a variant's curve passes -1 closely (gain margin 1.01 there too),
    # not the crossing at +4 deg on the plant tuned on
    assert 0.0 <= chk.phase_margin_deg < 30.0 and chk.phase_margin_plant != c.nominal
    assert abs(chk.phase_margin_hz - chk.gain_margin_hz) < 2.0
    assert chk.nominal_phase_margin_deg == pytest.approx(44.35, abs=0.5)
    assert "-17" not in c.check_text(chk)


def test_margins_cli_reports_the_distance(tmp_path):
    """distctrl margins --json on the audit's plant: no negative phase margin at the resonance."""
    import json

    from click.testing import CliRunner

    from distctrl.cli import main

    root = Path(__file__).resolve().parents[2]
    sc = tmp_path / "plant.toml"
    sc.write_text(f"""name = "audit M2 plant"
cycle_time = 0.001
program = "prog.nc"
duration = 0.5

[axes.X]
v_max = 500.0
a_max = 5000.0

[axes.Z]
params = "{root / 'examples' / 'scenarios' / 'z_laser.lis'}"
start = 40.0
kv = 60.0
v_max = 300.0
a_max = 20000.0
resonance_hz = 52.0
damping = 0.06

[surface]
base = 30.0

[sensor]
axis = "Z"
kind = "encoder"
noise_std = 0.003
delay_cycles = 3
seed = 5
""")
    (tmp_path / "prog.nc").write_text("N10 G90 G0 X0 Z31\nN20 Z[DIST_CTRL ON CONST_DIST SET_DIST=1]\n"
                                      "N30 G1 X400 F6000\nN40 M30\n")
    res = CliRunner().invoke(main, ["margins", str(sc), "--json"])
    assert res.exit_code == 0, res.output
    d = json.loads(res.output)
    pms = [row["phase_margin_deg"] for row in d["all_phase_margins"]]
    assert pms and min(pms) >= 0.0
    assert any(170.0 < pm < 180.0 for pm in pms)
