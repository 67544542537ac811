"""Compensation direction per MODE and its orthogonal effect (SPEC §11; FCT-M3 §12.1.3, §12.4.3)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from distctrl.kinematics import (CaHeadRtcp, CompensationMode, Frame, Plane, ca_tool_direction,
                                 clamping_point_distance, compensation_direction, compensation_vector,
                                 cs_rotation, inclination, orthogonal_change)

R = math.radians
Z = np.array([0.0, 0.0, 1.0])
angle = st.floats(-math.pi, math.pi)
incl = st.floats(0.0, math.pi / 2)
delta = st.floats(-10.0, 10.0)
coord = st.floats(-1000.0, 1000.0)


@pytest.mark.parametrize("mode", ["ACS", "MCS", "mcs", CompensationMode.ACS])
def test_acs_and_mcs_are_machine_z(mode):
    np.testing.assert_array_equal(compensation_direction(mode, ca_tool_direction(0.3, 0.7)), Z)


def test_pcs_follows_cs_rotation():
    np.testing.assert_array_equal(compensation_direction("PCS", None), Z)            # no #CS active
    rot = cs_rotation(30, 0, 0)
    np.testing.assert_allclose(compensation_direction("PCS", None, rot), (0, -0.5, math.cos(R(30))))
    np.testing.assert_allclose(compensation_direction("PCS", None, Frame(rot, (1, 2, 3))), rot[:, 2])
    with pytest.raises(ValueError):
        compensation_direction("PCS", None, np.diag([1.0, 1.0, 2.0]))               # not a rotation


def test_ecs_is_tool_direction_and_off_is_zero():
    u = ca_tool_direction(R(40), R(25))
    np.testing.assert_allclose(compensation_direction("ECS", 3 * u), u)
    np.testing.assert_array_equal(compensation_direction("OFF", u), np.zeros(3))
    assert orthogonal_change(2.0, compensation_direction("OFF", u), Z) == 0.0
    with pytest.raises(ValueError):
        compensation_direction("ECS", None)
    with pytest.raises(ValueError, match="unknown"):
        compensation_direction("WCS", u)


def test_example_inclined_30_degrees_ecs_vs_mcs():
    """Tool inclined by 30° on a horizontal workpiece: ECS changes the orthogonal distance by δ·cos 30°,
    MCS by δ (and keeps XY); the set distance seen orthogonally is SET_DIST·cos 30° (§12.9)."""
    u = ca_tool_direction(0.0, R(30))
    assert orthogonal_change(1.0, compensation_direction("ECS", u), Z) == pytest.approx(math.cos(R(30)))
    assert orthogonal_change(1.0, compensation_direction("MCS", u), Z) == 1.0


def test_robot_example_workpiece_inclined_30_degrees():
    """FCT-M3 §12.4.3.3: workpiece inclined by 30° in the PCS, tool perpendicular to it."""
    rot = cs_rotation(30, 0, 0)
    wp = Plane.from_frame(Frame(rot, (0, 0, 0)))
    u = wp.normal                                          # tool normal to the workpiece
    assert inclination(u) == pytest.approx(R(30))          # the head is inclined by 30° in the machine
    for mode, expected in (("PCS", 1.0), ("ECS", 1.0), ("MCS", math.cos(R(30))), ("ACS", math.cos(R(30)))):
        e = compensation_direction(mode, u, rot)
        assert orthogonal_change(1.0, e, wp.normal) == pytest.approx(expected)


@settings(max_examples=300)
@given(angle, incl, delta, st.tuples(coord, coord, coord), st.floats(0, 300), st.floats(-20, 20))
def test_ecs_changes_orthogonal_distance_by_delta_cos_theta(c, a, d, tcp, L, z0):
    """Move TCP and head by δ·u: the clamping point's orthogonal distance to a plane Z = z0 changes by δ·cos θ."""
    u = ca_tool_direction(c, a)
    th = inclination(u)
    e = compensation_direction("ECS", u)
    assert orthogonal_change(d, e, Z) == pytest.approx(d * math.cos(th), rel=1e-12, abs=1e-12)
    before = clamping_point_distance(tcp, u, L, (0, 0, z0), Z)
    after = clamping_point_distance(np.array(tcp) + compensation_vector("ECS", d, u), u, L, (0, 0, z0), Z)
    assert after - before == pytest.approx(d * math.cos(th), abs=1e-9)


@settings(max_examples=300)
@given(angle, incl, delta, st.tuples(coord, coord, coord))
def test_mcs_keeps_xy(c, a, d, tcp):
    """MCS: the XY projection of the contour stays (§12.1.3); only Z changes, by δ."""
    u = ca_tool_direction(c, a)
    head = CaHeadRtcp(80.0, 100.0)
    v = compensation_vector("MCS", d, u)
    new_tcp = np.array(tcp) + v
    assert new_tcp[0] == tcp[0] and new_tcp[1] == tcp[1]
    assert new_tcp[2] - tcp[2] == pytest.approx(d)
    p0, p1 = head.pivot_from_tcp(tcp, c, a), head.pivot_from_tcp(new_tcp, c, a)
    np.testing.assert_array_equal(p1[:2], p0[:2])
    assert orthogonal_change(d, compensation_direction("MCS", u), Z) == d


@given(angle, incl, delta)
def test_ecs_keeps_the_cutting_line(c, a, d):
    """ECS: the compensated TCP stays on the tool axis (cutting-curve orientation kept, §12.4.3)."""
    u = ca_tool_direction(c, a)
    shift = compensation_vector("ECS", d, u)
    assert np.linalg.norm(np.cross(shift, u)) == pytest.approx(0.0, abs=1e-12)


def test_vectorised_orthogonal_change():
    a = np.radians([0, 30, 60, 90])
    u = ca_tool_direction(0.0, a)
    np.testing.assert_allclose(orthogonal_change(2.0, u, Z), 2.0 * np.cos(a), atol=1e-15)
    v = compensation_vector("ECS", np.array([1.0, 2.0, 3.0, 4.0]), u)
    assert v.shape == (4, 3)
