"""CA head: tool direction, inverse angles, RTCP pivot <-> TCP (SPEC §11, FCT-M3 §12.1.2, §12.4.2)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from distctrl.kinematics import (CaAxes, CaHeadRtcp, Kinematic98Params, Plane, ca_angles_from_direction,
                                 ca_tool_direction, inclination)

R = math.radians
angle = st.floats(-4 * math.pi, 4 * math.pi, allow_nan=False)
incl = st.floats(0.0, math.pi, allow_nan=False)
coord = st.floats(-2000.0, 2000.0, allow_nan=False)
unit_vec = st.tuples(*[st.floats(-1, 1, allow_nan=False)] * 3).filter(lambda v: math.hypot(*v) > 1e-3)


def _wrap(x: float) -> float:
    return math.remainder(x, 2 * math.pi)


# --- tool direction: known values ---------------------------------------------------------------
@pytest.mark.parametrize("c_deg, a_deg, u", [
    (0, 0, (0, 0, 1)),
    (0, 90, (0, -1, 0)),              # A about X tilts +Z towards -Y
    (90, 90, (1, 0, 0)),              # then C = 90° turns it to +X
    (180, 90, (0, 1, 0)),
    (-90, 90, (-1, 0, 0)),
    (0, 180, (0, 0, -1)),
    (0, 30, (0, -0.5, math.cos(R(30)))),
    (90, 30, (0.5, 0, math.cos(R(30)))),
])
def test_tool_direction_known_values(c_deg, a_deg, u):
    np.testing.assert_allclose(ca_tool_direction(R(c_deg), R(a_deg)), u, atol=1e-15)


def test_tool_direction_is_rz_rx_applied_to_z():
    c, a = 0.7, -1.1
    rz = np.array([[math.cos(c), -math.sin(c), 0], [math.sin(c), math.cos(c), 0], [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    np.testing.assert_allclose(ca_tool_direction(c, a), rz @ rx @ [0, 0, 1], atol=1e-15)


def test_tool_direction_vectorised():
    c = np.linspace(-3, 3, 7)
    a = np.linspace(0, 2, 7)
    u = ca_tool_direction(c, a)
    assert u.shape == (7, 3)
    for i in range(7):
        np.testing.assert_allclose(u[i], ca_tool_direction(c[i], a[i]))
    assert ca_tool_direction(c[:, None], a[None, :]).shape == (7, 7, 3)


@given(angle, angle)
def test_direction_is_unit_and_inclination_is_abs_a(c, a):
    u = ca_tool_direction(c, a)
    assert np.linalg.norm(u) == pytest.approx(1.0, abs=1e-15)
    th = inclination(u)
    assert 0.0 <= th <= math.pi
    assert th == pytest.approx(abs(math.remainder(a, 2 * math.pi)), abs=1e-12)


@given(unit_vec)
def test_inclination_in_range_and_is_arccos_uz(v):
    u = np.array(v) / np.linalg.norm(v)
    th = inclination(v)
    assert 0.0 <= th <= math.pi
    assert math.cos(th) == pytest.approx(u[2], abs=1e-12)


def test_inclination_zero_vector_rejected():
    with pytest.raises(ValueError):
        inclination([0, 0, 0])


# --- inverse: angles from direction ---------------------------------------------------------------
@settings(max_examples=300)
@given(angle, st.floats(1e-6, math.pi - 1e-6), st.floats(-10, 10, allow_nan=False))
def test_angles_round_trip_with_hint(c, a, hint_shift):
    """angles -> direction -> angles: A recovered; C recovered when the hint is within π of it."""
    u = ca_tool_direction(c, a)
    hint = c + hint_shift * 0.3  # |shift| <= 3 < π
    c2, a2 = ca_angles_from_direction(u, hint)
    assert a2 == pytest.approx(a, abs=1e-9)
    assert c2 == pytest.approx(c, abs=1e-9 / math.sin(a) + 1e-12)
    assert abs(c2 - hint) <= math.pi + 1e-12


@settings(max_examples=300)
@given(unit_vec, st.one_of(st.none(), angle))
def test_direction_round_trip_any_direction(v, hint):
    """direction -> angles -> direction is the identity; A >= 0; C nearest to the hint."""
    c, a = ca_angles_from_direction(v, hint)
    assert 0.0 <= a <= math.pi
    np.testing.assert_allclose(ca_tool_direction(c, a), np.array(v) / np.linalg.norm(v), atol=1e-12)
    if hint is None:
        assert -math.pi <= c <= math.pi
    else:
        assert abs(c - hint) <= math.pi + 1e-9


def test_negative_a_comes_back_on_the_a_positive_branch():
    """PROG #DIST CTRL example 2 programs A=-45° (C=0): the same direction is A=+45°, C=±180°."""
    u = ca_tool_direction(0.0, R(-45))
    np.testing.assert_allclose(u, (0, math.sqrt(0.5), math.sqrt(0.5)), atol=1e-15)
    c, a = ca_angles_from_direction(u, c_hint=0.0)
    assert a == pytest.approx(R(45))
    assert abs(c) == pytest.approx(math.pi)
    c, a = ca_angles_from_direction(u, c_hint=R(170))
    assert c == pytest.approx(math.pi)
    c, a = ca_angles_from_direction(u, c_hint=R(-170))
    assert c == pytest.approx(-math.pi)


def test_c_nearest_to_hint_over_several_turns():
    u = ca_tool_direction(R(30), R(20))
    c, _ = ca_angles_from_direction(u, c_hint=R(30 + 720 + 100))
    assert c == pytest.approx(R(30 + 720))
    c, _ = ca_angles_from_direction(u)
    assert c == pytest.approx(R(30))


@pytest.mark.parametrize("u", [(0, 0, 1), (0, 0, 5), (0, 0, -1), (1e-14, -1e-14, 1)])
@pytest.mark.parametrize("hint", [None, 0.3, -7.0])
def test_singular_orientation_keeps_c_hint(u, hint):
    c, a = ca_angles_from_direction(u, hint)
    assert c == (0.0 if hint is None else hint)
    assert a == pytest.approx(0.0 if u[2] > 0 else math.pi, abs=1e-13)


def test_inverse_vectorised():
    c = np.array([0.1, 1.0, -2.0, 0.0])
    a = np.array([0.2, 1.5, 3.0, 0.0])
    u = ca_tool_direction(c, a)
    c2, a2 = ca_angles_from_direction(u, c_hint=np.array([0.0, 1.0, -2.0, 0.4]))
    np.testing.assert_allclose(a2, a, atol=1e-12)
    np.testing.assert_allclose(c2, [0.1, 1.0, -2.0, 0.4], atol=1e-12)   # last one singular: hint kept


# --- RTCP: pivot <-> TCP ------------------------------------------------------------------------
def test_pivot_upright_and_inclined():
    """§12.1.2 constant TCP: the TCP stays, the pivot moves with the inclination."""
    head = CaHeadRtcp(tool_length=80.0, hd1=100.0)
    tcp = np.array([10.0, 20.0, 0.0])
    np.testing.assert_allclose(head.pivot_from_tcp(tcp, 0.0, 0.0), (10, 20, 180))
    np.testing.assert_allclose(head.pivot_from_tcp(tcp, 0.0, R(30)),
                               (10, 20 - 180 * 0.5, 180 * math.cos(R(30))), atol=1e-12)
    np.testing.assert_allclose(head.pivot_from_tcp(tcp, R(90), R(90)), (190, 20, 0), atol=1e-12)


@settings(max_examples=200)
@given(st.tuples(coord, coord, coord), angle, angle, st.floats(0, 500), st.floats(-50, 500))
def test_pivot_tcp_round_trip_and_sphere(tcp, c, a, L, hd1):
    head = CaHeadRtcp(L, hd1)
    pivot = head.pivot_from_tcp(tcp, c, a)
    np.testing.assert_allclose(head.tcp_from_pivot(pivot, c, a), tcp, atol=1e-9)
    # TCP fixed, orientation varied: the pivot lies on the sphere of radius L + HD1 around the TCP
    assert np.linalg.norm(pivot - np.array(tcp)) == pytest.approx(abs(L + hd1), abs=1e-9)


@given(st.tuples(coord, coord, coord), st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda v: math.hypot(*v) > 1e-3),
       st.one_of(st.none(), angle))
def test_machine_axes_round_trip(tcp, u, hint):
    head = CaHeadRtcp(120.0, 35.0)
    axes = head.machine_axes(tcp, u, hint)
    assert isinstance(axes, CaAxes) and axes.a >= 0.0
    np.testing.assert_allclose(head.tcp_from_axes(axes), tcp, atol=1e-9)
    np.testing.assert_allclose([axes.x, axes.y, axes.z],
                               np.array(tcp) + 155.0 * np.array(u) / np.linalg.norm(u), atol=1e-9)


def test_vectorised_pivot():
    head = CaHeadRtcp(80.0, 100.0)
    tcp = np.zeros((5, 3))
    a = np.linspace(0, math.pi / 2, 5)
    p = head.pivot_from_tcp(tcp, 0.0, a)
    assert p.shape == (5, 3)
    np.testing.assert_allclose(np.linalg.norm(p, axis=1), 180.0)


def test_head_validation():
    with pytest.raises(ValueError):
        CaHeadRtcp(-1.0)
    with pytest.raises(ValueError):
        CaHeadRtcp(float("nan"))
    with pytest.raises(ValueError, match="HD1"):
        CaHeadRtcp(80.0, 0.0, Kinematic98Params.from_raw(1000000, 300000, 600000, 910000))


# --- with kinematic 98 (§12.4.2.1 CA example, §12.4.2.2 orientations in the plane) ---------------
K001 = Kinematic98Params.from_raw(1000000, 300000, 600000, 910000)   # PROG #DIST CTRL: 100 mm, 30°, 60°, 91°


def test_kin98_head_keeps_clamping_point_height_in_the_band():
    head = CaHeadRtcp.with_kin98(80.0, K001)
    floor = Plane.horizontal(0.0)
    tcp = (0.0, 0.0, 0.0)
    heights = {deg: head.clamping_point_distance(tcp, 0.0, R(deg), floor) for deg in range(0, 91, 5)}
    for deg, h in heights.items():
        if deg <= 30:
            assert h == pytest.approx(80.0 * math.cos(R(deg)))      # phase 1: L·cos θ
        elif deg <= 60:
            assert h == pytest.approx(80.0 * math.cos(R(30)))       # phase 2: constant height
        else:
            assert h == pytest.approx(80.0 * math.cos(R(30)) / math.cos(R(60)) * math.cos(R(deg)))
    # the pivot follows the virtual length: |pivot - TCP| = Lv + HD1
    assert np.linalg.norm(head.pivot_from_tcp(tcp, 0.0, R(45))) == pytest.approx(
        80 * math.cos(R(30)) / math.cos(R(45)) + 100.0)


@given(angle, angle, st.floats(0, math.pi / 2))
def test_kin98_independent_of_c(c1, c2, a):
    """§12.4.2.2: the minimum-distance monitoring does not depend on the C orientation."""
    head = CaHeadRtcp.with_kin98(80.0, K001)
    floor = Plane.horizontal(-3.0)
    tcp = (5.0, -7.0, -3.0)
    d1 = head.clamping_point_distance(tcp, c1, a, floor)
    d2 = head.clamping_point_distance(tcp, c2, a, floor)
    assert d1 == pytest.approx(d2, abs=1e-9)
    assert head.pivot_distance(a) == pytest.approx(K001.virtual_tool_length(80.0, a) + 100.0)
