"""Kinematic 98: parameter conversion and validation, virtual tool length, maximum inclination.

FCT-M3 §12.4.2 (offset data table), §12.4.2.1 (CA example), §12.9 (application examples
[90°;-], [0°;-], [30°;60°], [10°;31°]); PROG #DIST CTRL example 2; SPEC §11/§12.
"""
from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from distctrl.errors import ParameterError
from distctrl.kinematics import (KIN98_MAX_INCLINATION_EXCEEDED, InclinationViolation, Kinematic98Params,
                                 orthogonal_set_distance)

R = math.radians
L = 80.0   # tool length of every document example (V.G.WZ_AKT.L = 80)


# --- raw conversion -------------------------------------------------------------------------------
def test_prog_dist_ctrl_values_convert_exactly():
    """PROG #DIST CTRL: PARAM[0..3] = 1000000, 300000, 600000, 910000 -> 100 mm, 30°, 60°, 91°."""
    p = Kinematic98Params.from_raw(1000000, 300000, 600000, 910000)
    assert p.hd1_mm == 100.0
    assert p.hd2_rad == math.radians(30.0)
    assert p.hd3_rad == math.radians(60.0)
    assert p.hd4_rad == math.radians(91.0)
    assert p.to_raw() == (1000000, 300000, 600000, 910000)


def test_fct_m3_ca_example_values():
    """FCT-M3 §12.4.2.1: 100000 (HD1 = 10 mm), 500000 (50°), 700000 (70°), 910000 (91°)."""
    p = Kinematic98Params.from_raw(100000, 500000, 700000, 910000)
    assert (p.hd1_mm, p.hd2_rad, p.hd3_rad, p.hd4_rad) == (10.0, R(50.0), R(70.0), R(91.0))


def test_fct_m3_programming_example_is_decoded_literally():
    """FCT-M3 §12.2 ex. 2 is off by 10 against its comments (SPEC §12): the units are applied
    as documented, the values are not "repaired" — 100000/30000/60000/91000 are 10 mm, 3°, 6°, 9.1°."""
    p = Kinematic98Params.from_raw(100000, 30000, 60000, 91000)
    assert (p.hd1_mm, p.hd2_rad, p.hd3_rad, p.hd4_rad) == (10.0, R(3.0), R(6.0), R(9.1))


@given(st.integers(-10**7, 10**7), st.integers(0, 899999), st.integers(0, 899999), st.integers(0, 1800000))
def test_raw_round_trip(p0, a, b, c):
    p1, p2 = sorted((a, b))
    p3 = p2 + c % (1800001 - p2)          # HD3 <= HD4 <= 180°
    p = Kinematic98Params.from_raw(p0, p1, p2, p3)
    assert p.to_raw() == (p0, p1, p2, p3)


def test_from_degrees_matches_from_raw():
    assert Kinematic98Params.from_degrees(100, 30, 60, 91) == Kinematic98Params.from_raw(1000000, 300000, 600000, 910000)


# --- validation --------------------------------------------------------------------------------------
@pytest.mark.parametrize("raw, param", [
    ((0, -10000, 300000, 400000), "PARAM[1]"),        # HD2 < 0
    ((0, 910000, 910000, 910000), "PARAM[1]"),        # HD2 > 90°
    ((0, 300000, 200000, 400000), "PARAM[2]"),        # HD3 < HD2
    ((0, 300000, 900000, 910000), "PARAM[2]"),        # HD3 = 90° > HD2: infinite extension
    ((0, 300000, 950000, 960000), "PARAM[2]"),        # HD3 > 90°
    ((0, 300000, 600000, 500000), "PARAM[3]"),        # HD4 < HD3
    ((0, 300000, 600000, 1800001), "PARAM[3]"),       # HD4 > 180°
    ((float("nan"), 0, 0, 0), "PARAM[0]"),
    ((0, 0, float("inf"), 0), "PARAM[2]"),
])
def test_invalid_parameters_name_the_param(raw, param):
    with pytest.raises(ValueError, match=param.replace("[", r"\[").replace("]", r"\]")) as exc:
        Kinematic98Params.from_raw(*raw)
    assert isinstance(exc.value, ParameterError)
    assert exc.value.key == f"V.G.KIN_STEP[1].ID[98].{param}"


def test_direct_construction_is_validated_too():
    with pytest.raises(ParameterError, match=r"PARAM\[2\]"):
        Kinematic98Params(0.0, R(30), R(20), R(40))


@pytest.mark.parametrize("raw", [
    (1000000, 300000, 600000, 910000),   # HD4 = 91° (both documents' examples)
    (0, 900000, 900000, 910000),         # [90°; -]: HD2 = HD3 = 90° (no extension)
    (0, 0, 0, 0),
    (0, 0, 890000, 1800000),
    (-50000, 100000, 310000, 310000),    # HD3 = HD4
])
def test_valid_edge_parameters(raw):
    Kinematic98Params.from_raw(*raw)


# --- virtual tool length: application examples §12.9 ----------------------------------------------
def test_example_4_10_to_31_degrees():
    """[10°; 31°]: Lv = L below 10°, L·cos10°/cosθ between, constant L·cos10°/cos31° above 31°."""
    p = Kinematic98Params.from_degrees(0, 10, 31, 91)
    assert p.virtual_tool_length(L, R(0)) == L
    assert p.virtual_tool_length(L, R(9.999)) == L
    assert p.virtual_tool_length(L, R(10)) == L
    for deg in (12.5, 20, 25, 30.9, 31):
        assert p.virtual_tool_length(L, R(deg)) == pytest.approx(L * math.cos(R(10)) / math.cos(R(deg)), rel=1e-15)
    top = L * math.cos(R(10)) / math.cos(R(31))
    for deg in (31.001, 45, 60, 90, 91):
        assert p.virtual_tool_length(L, R(deg)) == pytest.approx(top, rel=1e-15)
    # the head (clamping point) height L_v·cos θ is L·cos10° inside the band (phase 2)
    for deg in (10, 17, 24, 31):
        assert p.virtual_tool_length(L, R(deg)) * math.cos(R(deg)) == pytest.approx(L * math.cos(R(10)))


def test_example_3_30_to_60_degrees_prog_dist_ctrl():
    p = Kinematic98Params.from_raw(1000000, 300000, 600000, 910000)
    assert p.virtual_tool_length(L, R(20)) == L
    assert p.virtual_tool_length(L, R(45)) == pytest.approx(L * math.cos(R(30)) / math.cos(R(45)))
    assert p.virtual_tool_length(L, R(75)) == pytest.approx(L * math.cos(R(30)) / math.cos(R(60)))
    assert p.max_extension_factor == pytest.approx(math.sqrt(3))


def test_example_1_90_degrees_no_monitoring():
    """[90°; -]: no height monitoring during the whole inclination 0°..90° (Lv = L)."""
    p = Kinematic98Params.from_degrees(0, 90, 90, 91)
    for deg in (0, 30, 60, 89.9, 90, 91):
        assert p.virtual_tool_length(L, R(deg)) == L


def test_example_2_0_degrees_kept_from_the_start():
    """[0°; -]: the head height is kept constant from the start of the inclination (here up to HD3 = 85°)."""
    p = Kinematic98Params.from_degrees(0, 0, 85, 85)
    for deg in (0, 10, 45, 80, 85):
        assert p.virtual_tool_length(L, R(deg)) * math.cos(R(deg)) == pytest.approx(L)


def test_vectorised_and_signed_inclination():
    import numpy as np
    p = Kinematic98Params.from_degrees(0, 10, 31, 91)
    th = np.radians([0, 5, 10, 20, 31, 40])
    lv = p.virtual_tool_length(L, th)
    assert lv.shape == (6,)
    assert lv[0] == lv[1] == lv[2] == L
    assert p.virtual_tool_length(L, -th[3]) == lv[3]        # A = -20° inclines by 20°
    with pytest.raises(ValueError):
        p.virtual_tool_length(-1.0, 0.1)


hd_pair = st.tuples(st.floats(0, 89.9), st.floats(0, 89.9)).map(sorted)


@settings(max_examples=300)
@given(hd_pair, st.floats(0.0, 500.0))
def test_continuous_at_hd2_and_hd3(hd, length):
    hd2, hd3 = hd
    p = Kinematic98Params.from_degrees(0, hd2, hd3, 180)
    eps = 1e-9
    for edge in (R(hd2), R(hd3)):
        below = p.virtual_tool_length(length, max(edge - eps, 0.0))
        at = p.virtual_tool_length(length, edge)
        above = p.virtual_tool_length(length, edge + eps)
        assert below == pytest.approx(at, rel=1e-6, abs=1e-12)
        assert above == pytest.approx(at, rel=1e-6, abs=1e-12)
    assert p.virtual_tool_length(length, R(hd2)) == length          # exactly L at the start angle


@settings(max_examples=300)
@given(hd_pair, st.floats(0.0, 500.0), st.lists(st.floats(0, math.pi), min_size=2, max_size=20))
def test_non_decreasing_in_theta(hd, length, thetas):
    p = Kinematic98Params.from_degrees(0, hd[0], hd[1], 180)
    lv = [p.virtual_tool_length(length, t) for t in sorted(thetas)]
    assert all(b >= a * (1 - 1e-15) for a, b in zip(lv, lv[1:]))
    assert all(length <= v <= length * p.max_extension_factor * (1 + 1e-15) for v in lv)


# --- maximum inclination HD4 -------------------------------------------------------------------------
def test_check_inclination_beyond_hd4():
    p = Kinematic98Params.from_raw(1000000, 300000, 600000, 910000)
    assert p.check_inclination(R(45)) is None
    assert p.check_inclination(R(91)) is None                       # exactly HD4 is allowed
    v = p.check_inclination(R(91.0001))
    assert isinstance(v, InclinationViolation)
    assert v.id == KIN98_MAX_INCLINATION_EXCEEDED == 900020
    assert "PARAM[3]" in v.message and "91.0000°" in v.message
    assert p.check_inclination(-R(95)) is not None                  # by magnitude
    assert p.check_inclination(float("nan")) is not None
    assert p.exceeds_max_inclination(R(92)) is True


# --- orthogonal set distance (SPEC §11) ------------------------------------------------------------
def test_orthogonal_set_distance_cos_theta():
    assert orthogonal_set_distance(1.0, R(30)) == pytest.approx(math.cos(R(30)))
    assert orthogonal_set_distance(80.0, 0.0) == 80.0
    assert orthogonal_set_distance(80.0, R(90)) == pytest.approx(0.0, abs=1e-12)


def test_orthogonal_set_distance_with_kin98():
    p = Kinematic98Params.from_degrees(0, 10, 31, 91)
    assert orthogonal_set_distance(L, R(5), p) == pytest.approx(L * math.cos(R(5)))
    for deg in (10, 20, 31):
        assert orthogonal_set_distance(L, R(deg), p) == pytest.approx(L * math.cos(R(10)))
    assert orthogonal_set_distance(L, R(50), p) == pytest.approx(
        L * math.cos(R(10)) / math.cos(R(31)) * math.cos(R(50)))
