"""#CS rotation (intrinsic Z-Y'-X'', ISG default P-CHAN-00394 = ZYX) and frames."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from distctrl.kinematics import (ROTATION_SEQUENCES, Frame, cs_angles_from_rotation, cs_rotation, rot_x, rot_y,
                                 rot_z)

R = math.radians
deg = st.floats(-360.0, 360.0)


def test_single_axis_rotations_known_values():
    np.testing.assert_allclose(cs_rotation(90, 0, 0) @ [0, 1, 0], (0, 0, 1), atol=1e-15)   # A about X
    np.testing.assert_allclose(cs_rotation(0, 90, 0) @ [0, 0, 1], (1, 0, 0), atol=1e-15)   # B about Y
    np.testing.assert_allclose(cs_rotation(0, 0, 90) @ [1, 0, 0], (0, 1, 0), atol=1e-15)   # C about Z
    np.testing.assert_allclose(cs_rotation(30, 0, 0)[:, 2], (0, -0.5, math.cos(R(30))), atol=1e-15)


def test_default_order_is_z_then_y_then_x():
    """R = Rz(C)·Ry(B)·Rx(A): first about Z, then about the new Y', then about X''."""
    a, b, c = 10.0, 20.0, 30.0
    np.testing.assert_allclose(cs_rotation(a, b, c), rot_z(R(c)) @ rot_y(R(b)) @ rot_x(R(a)), atol=1e-15)
    # equivalently extrinsic X, then Y, then Z about the fixed machine axes
    np.testing.assert_allclose(cs_rotation(a, b, c),
                               Rotation.from_euler("xyz", [a, b, c], degrees=True).as_matrix(), atol=1e-14)
    # order matters: a different sequence gives a different matrix
    assert not np.allclose(cs_rotation(a, b, c), cs_rotation(a, b, c, "XYZ"))


@settings(max_examples=200)
@given(deg, deg, deg, st.sampled_from(ROTATION_SEQUENCES))
def test_matches_scipy_intrinsic_sequences(a, b, c, seq):
    ang = {"X": a, "Y": b, "Z": c}
    expected = Rotation.from_euler(seq, [ang[k] for k in seq], degrees=True).as_matrix()  # upper = intrinsic
    r = cs_rotation(a, b, c, seq)
    np.testing.assert_allclose(r, expected, atol=1e-12)
    np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0)


@settings(max_examples=200)
@given(st.floats(-180, 180), st.floats(-89.9, 89.9), st.floats(-180, 180))
def test_angles_round_trip(a, b, c):
    a2, b2, c2 = cs_angles_from_rotation(cs_rotation(a, b, c))
    np.testing.assert_allclose(cs_rotation(a2, b2, c2), cs_rotation(a, b, c), atol=1e-12)
    assert b2 == pytest.approx(b, abs=1e-9)


def test_gimbal_lock_inverse():
    r = cs_rotation(25, 90, 40)
    a, b, c = cs_angles_from_rotation(r)
    assert a == 0.0 and b == pytest.approx(90)
    np.testing.assert_allclose(cs_rotation(a, b, c), r, atol=1e-12)


def test_invalid_sequence_and_angles():
    with pytest.raises(ValueError, match="sequence"):
        cs_rotation(1, 2, 3, "ZYZ")
    with pytest.raises(ValueError):
        cs_rotation(float("nan"), 0, 0)


@settings(max_examples=100)
@given(st.tuples(*[st.floats(-500, 500)] * 3), deg, deg, deg, st.tuples(*[st.floats(-500, 500)] * 3))
def test_frame_round_trip_and_inverse(origin, a, b, c, p):
    f = Frame.from_cs(*origin, a, b, c)
    q = f.to_machine(p)
    np.testing.assert_allclose(f.to_programmed(q), p, atol=1e-9)
    np.testing.assert_allclose(f.inverse().to_machine(q), p, atol=1e-9)
    np.testing.assert_allclose(f.direction_to_machine((0, 0, 1)), f.z_axis, atol=1e-15)
    np.testing.assert_allclose(f.direction_to_programmed(f.z_axis), (0, 0, 1), atol=1e-12)


def test_frame_nesting_and_validation():
    outer = Frame.from_cs(10, 0, 0, 0, 0, 90)
    inner = Frame.from_cs(0, 5, 0, 30, 0, 0)
    both = outer.then(inner)
    p = np.array([1.0, 2.0, 3.0])
    np.testing.assert_allclose(both.to_machine(p), outer.to_machine(inner.to_machine(p)), atol=1e-12)
    with pytest.raises(ValueError):
        Frame(np.diag([1.0, 1.0, -1.0]), (0, 0, 0))        # a reflection is not a #CS
    assert "A=10" in repr(Frame.from_cs(0, 0, 0, 10, 20, 30))
