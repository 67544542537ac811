"""Planes, height fields and distances (FCT-M3 §12.3, §12.4.1; SPEC §11)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from distctrl.kinematics import (HeightField, Plane, angle_between, ca_tool_direction, clamping_point,
                                 clamping_point_distance, cs_rotation, distance_along, inclination,
                                 orthogonal_distance, surface_normal)

R = math.radians
coord = st.floats(-1000.0, 1000.0, allow_nan=False)
point = st.tuples(coord, coord, coord)
direction = st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda v: math.hypot(*v) > 1e-2)


def test_orthogonal_distance_known():
    assert orthogonal_distance((1, 2, 5), (0, 0, 2), (0, 0, 1)) == 3.0
    assert orthogonal_distance((1, 2, 5), (0, 0, 2), (0, 0, 7)) == 3.0          # normal normalised
    assert orthogonal_distance((1, 2, -1), (0, 0, 2), (0, 0, 1)) == -3.0        # below: negative
    n = cs_rotation(30, 0, 0)[:, 2]                                             # 30° inclined workpiece
    assert orthogonal_distance((0, 0, 10), (0, 0, 0), n) == pytest.approx(10 * math.cos(R(30)))


def test_orthogonal_distance_vectorised():
    pts = np.array([[0, 0, 1], [0, 0, 2], [5, 5, 3]], dtype=float)
    np.testing.assert_allclose(orthogonal_distance(pts, (0, 0, 0), (0, 0, 1)), [1, 2, 3])


def test_distance_along_known():
    assert distance_along((0, 0, 10), (0, 0, -1), (0, 0, 0), (0, 0, 1)) == 10.0
    assert distance_along((0, 0, 10), (0, 0, 1), (0, 0, 0), (0, 0, 1)) == -10.0   # plane behind
    d = (math.sin(R(30)), 0, -math.cos(R(30)))
    assert distance_along((0, 0, 10), d, (0, 0, 0), (0, 0, 1)) == pytest.approx(10 / math.cos(R(30)))
    assert distance_along((0, 0, 10), (0, 0, -5), (0, 0, 0), (0, 0, 1)) == 10.0   # direction normalised
    assert math.isnan(distance_along((0, 0, 10), (1, 0, 0), (0, 0, 0), (0, 0, 1)))  # parallel


@settings(max_examples=200)
@given(point, direction, point, direction)
def test_distance_along_lands_on_plane(p, d, p0, n):
    t = distance_along(p, d, p0, n)
    nn = np.array(n) / np.linalg.norm(n)
    dd = np.array(d) / np.linalg.norm(d)
    if abs(nn @ dd) < 1e-3:
        return
    hit = np.array(p) + t * dd
    assert orthogonal_distance(hit, p0, n) == pytest.approx(0.0, abs=1e-8)
    # and relates to the orthogonal distance: t = -d_orth / (n·d)
    assert t == pytest.approx(-orthogonal_distance(p, p0, n) / (nn @ dd), rel=1e-9, abs=1e-9)


def test_invalid_vectors():
    with pytest.raises(ValueError):
        orthogonal_distance((0, 0, 0), (0, 0, 0), (0, 0, 0))
    with pytest.raises(ValueError):
        distance_along((0, 0, 0), (0, 0, float("nan")), (0, 0, 0), (0, 0, 1))
    with pytest.raises(ValueError):
        Plane((0, 0), (0, 0, 1))


def test_surface_normal_and_angle_between():
    np.testing.assert_allclose(surface_normal(0.0, 0.0), (0, 0, 1))
    n = surface_normal(math.tan(R(30)), 0.0)
    np.testing.assert_allclose(n, (-math.sin(R(30)), 0, math.cos(R(30))), atol=1e-15)
    assert angle_between((0, 0, 1), n) == pytest.approx(R(30))
    assert angle_between(n, n) == pytest.approx(0.0, abs=1e-15)
    assert inclination(n) == pytest.approx(R(30))


# --- clamping point (laser exit) distance -----------------------------------------------------------
@given(st.floats(0, 500), st.floats(-math.pi, math.pi), st.floats(0, math.pi / 2), st.tuples(coord, coord))
def test_clamping_point_distance_is_l_cos_theta(L, c, a, xy):
    """TCP on the surface: the orthogonal distance of the clamping point is L·cos θ (§12.1.2, SPEC §11)."""
    u = ca_tool_direction(c, a)
    tcp = (xy[0], xy[1], 2.5)
    d = clamping_point_distance(tcp, u, L, (0, 0, 2.5), (0, 0, 1))
    assert d == pytest.approx(L * math.cos(a), abs=1e-9)
    # the beam from the clamping point back along -u reaches the surface after L
    if a < R(89):
        assert distance_along(clamping_point(tcp, u, L), -u, (0, 0, 2.5), (0, 0, 1)) == pytest.approx(L, abs=1e-9)


def test_clamping_point_on_inclined_workpiece():
    """FCT-M3 §12.4.3.3: workpiece inclined by 30°; tool normal to it -> L; tool vertical -> L·cos 30°."""
    rot = cs_rotation(30, 0, 0)
    wp = Plane((0, 0, 0), rot[:, 2])
    assert clamping_point_distance((0, 0, 0), rot[:, 2], 80.0, wp.point, wp.normal) == pytest.approx(80.0)
    assert clamping_point_distance((0, 0, 0), (0, 0, 1), 80.0, wp.point, wp.normal) == pytest.approx(
        80.0 * math.cos(R(30)))


# --- Plane object ----------------------------------------------------------------------------------
def test_plane_object():
    p = Plane((0, 0, 3), (0, 0, 2))
    np.testing.assert_allclose(p.normal, (0, 0, 1))
    assert p.orthogonal_distance((4, 4, 7)) == 4.0
    assert p.distance_along((4, 4, 7), (0, 0, -1)) == 4.0
    np.testing.assert_allclose(p.foot_point((4, 4, 7)), (4, 4, 3))
    assert Plane.horizontal(1.5).orthogonal_distance((0, 0, 2)) == 0.5


# --- height fields ------------------------------------------------------------------------------------
TILT = math.tan(R(30))


@pytest.mark.parametrize("with_gradient", [True, False])
@settings(max_examples=60, deadline=None)
@given(point, direction)
def test_height_field_tilted_plane_equals_plane(with_gradient, p, d):
    hf = HeightField(lambda x, y: 2.0 + TILT * x, (lambda x, y: (TILT, 0.0)) if with_gradient else None)
    plane = Plane((0, 0, 2.0), surface_normal(TILT, 0.0))
    tol = 1e-7 if with_gradient else 1e-5
    assert hf.orthogonal_distance(p) == pytest.approx(plane.orthogonal_distance(p), abs=tol)
    np.testing.assert_allclose(hf.normal_at(p), plane.normal, atol=1e-8)
    t_plane = plane.distance_along(p, d)
    t_hf = hf.distance_along(p, d)
    if math.isfinite(t_plane) and abs(np.dot(plane.normal, d) / np.linalg.norm(d)) > 1e-2:
        assert t_hf == pytest.approx(t_plane, rel=1e-7, abs=tol)


def _pipe(radius: float) -> HeightField:
    """Upper half of a pipe along Y (a pipe feedthrough, §12.1.3): z = sqrt(r² − x²)."""
    return HeightField(lambda x, y: math.sqrt(radius ** 2 - x ** 2),
                       lambda x, y: (-x / math.sqrt(radius ** 2 - x ** 2), 0.0))


@settings(max_examples=100, deadline=None)
@given(st.floats(-40, 40), st.floats(-100, 100), st.floats(0.0, 20.0))
def test_height_field_pipe_orthogonal_distance(phi_deg, y, d):
    """The orthogonal distance to a cylinder of radius r is |p − axis| − r."""
    r = 50.0
    phi = R(phi_deg)
    p = ((r + d) * math.sin(phi), y, (r + d) * math.cos(phi))
    pipe = _pipe(r)
    assert pipe.orthogonal_distance(p) == pytest.approx(d, abs=1e-8)
    np.testing.assert_allclose(pipe.foot_point(p), (r * math.sin(phi), y, r * math.cos(phi)), atol=1e-7)
    np.testing.assert_allclose(pipe.normal_at(pipe.foot_point(p)), (math.sin(phi), 0, math.cos(phi)), atol=1e-8)
    # along the radial direction back to the surface: distance d
    assert pipe.distance_along(p, (-math.sin(phi), 0, -math.cos(phi))) == pytest.approx(d, abs=1e-8)


def test_height_field_from_surface_like_object():
    class Sim:     # duck-typed like distctrl.sim.surface.Surface: height() and gradient()
        def height(self, x, y):
            return 1.0 + 0.1 * y

        def gradient(self, x, y):
            return (0.0, 0.1)

    hf = HeightField.from_surface(Sim())
    assert hf.vertical_distance((0, 10, 5)) == pytest.approx(3.0)
    assert hf.orthogonal_distance((0, 10, 5)) == pytest.approx(3.0 / math.sqrt(1.01))


def test_height_field_no_intersection_is_nan():
    hf = HeightField(lambda x, y: 0.0, lambda x, y: (0.0, 0.0))
    assert math.isnan(hf.distance_along((0, 0, 1), (1, 0, 0)))
