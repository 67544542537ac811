"""#CS rotation and frames: the programmed coordinate system (PCS) in machine coordinates.

Convention (decision, docs/kinematics.md): ``cs_rotation(a, b, c)`` is the *intrinsic* rotation
sequence Z, Y', X'' (yaw-pitch-roll)::

    R = R_z(C) · R_y(B) · R_x(A)

A rotates about X, B about Y, C about Z, right-handed (positive = counter-clockwise looking down
the axis towards the origin). Why: it is the ISG kernel's default rotation sequence for coordinate
systems (channel parameter P-CHAN-00394 ``coordinate_system.rotation_sequence``, default ``ZYX``,
changeable per program with ``#CS MODE ON [ROTATION_SEQUENCE ..]``), the DIN 9300 roll/pitch/yaw
rule. The other five Tait-Bryan sequences are available through ``sequence`` (letters = intrinsic
order; the angle for X is always A, for Y B, for Z C).

The columns of ``R`` are the programmed X, Y, Z axes expressed in machine coordinates, so a point
``p`` given in the #CS is ``origin + R·p`` in machine coordinates and the programmed Z direction
(the PCS compensation direction of SPEC §11) is ``R[:, 2]``. Angles in degrees at this edge (they
come from NC words), radians inside.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
import numpy as np
from numpy.typing import ArrayLike

__all__ = ["cs_rotation", "cs_angles_from_rotation", "rot_x", "rot_y", "rot_z", "check_rotation",
           "Frame", "ROTATION_SEQUENCES", "DEFAULT_ROTATION_SEQUENCE"]

#: Tait-Bryan sequences accepted (intrinsic order); P-CHAN-00394's proper-Euler ones (XYX, ZYZ, ...)
#: are not supported because one letter would need two of the angles A, B, C.
ROTATION_SEQUENCES = ("ZYX", "ZXY", "YXZ", "YZX", "XYZ", "XZY")
DEFAULT_ROTATION_SEQUENCE = "ZYX"


def rot_x(angle: float) -> np.ndarray:
    """Rotation by ``angle`` (rad) about X."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle: float) -> np.ndarray:
    """Rotation by ``angle`` (rad) about Y."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle: float) -> np.ndarray:
    """Rotation by ``angle`` (rad) about Z."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


_ROT = {"X": rot_x, "Y": rot_y, "Z": rot_z}


def cs_rotation(a_deg: float, b_deg: float, c_deg: float,
                sequence: str = DEFAULT_ROTATION_SEQUENCE) -> np.ndarray:
    """Rotation matrix of a #CS with angles A (about X), B (about Y), C (about Z) in degrees.

    Default ``ZYX``: ``R = R_z(C)·R_y(B)·R_x(A)`` (intrinsic Z, Y', X''); for a sequence
    ``s1 s2 s3`` in general ``R = R_s1·R_s2·R_s3``. See the module docstring for why.
    """
    seq = str(sequence).upper()
    if seq not in ROTATION_SEQUENCES:
        raise ValueError(f"rotation sequence {sequence!r} not supported; allowed: {', '.join(ROTATION_SEQUENCES)}")
    ang = {"X": a_deg, "Y": b_deg, "Z": c_deg}
    for k, v in ang.items():
        if not math.isfinite(float(v)):
            raise ValueError(f"#CS rotation angle about {k} must be finite, got {v!r}")
    r = np.eye(3)
    for axis in seq:
        r = r @ _ROT[axis](math.radians(float(ang[axis])))
    return r


def cs_angles_from_rotation(rotation: ArrayLike) -> tuple[float, float, float]:
    """Inverse of ``cs_rotation(a, b, c)`` for the default ``ZYX`` sequence: ``(A, B, C)`` in degrees.

    ``B = atan2(−R20, sqrt(R00² + R10²)) ∈ [−90°, 90°]``, ``A = atan2(R21, R22)``,
    ``C = atan2(R10, R00)``; at ``|B| = 90°`` (gimbal lock) ``A = 0`` and ``C = atan2(−R01, R11)``.
    """
    r = check_rotation(rotation)
    cb = math.hypot(r[0, 0], r[1, 0])
    b = math.atan2(-r[2, 0], cb)
    if cb > 1e-12:
        a = math.atan2(r[2, 1], r[2, 2])
        c = math.atan2(r[1, 0], r[0, 0])
    else:
        a = 0.0
        c = math.atan2(-r[0, 1], r[1, 1])
    return math.degrees(a), math.degrees(b), math.degrees(c)


def check_rotation(rotation: ArrayLike, *, tol: float = 1e-9) -> np.ndarray:
    """``rotation`` as a float (3, 3) array; ``ValueError`` unless ``RᵀR = I`` (within ``tol``) and ``det R > 0``."""
    r = np.asarray(rotation, dtype=float)
    if r.shape != (3, 3) or not np.all(np.isfinite(r)):
        raise ValueError(f"rotation must be a finite 3x3 matrix, got shape {r.shape}")
    if np.max(np.abs(r.T @ r - np.eye(3))) > tol or np.linalg.det(r) <= 0:
        raise ValueError("rotation must be a proper rotation matrix (orthonormal, det = +1)")
    return r


@dataclass(frozen=True, eq=False)
class Frame:
    """A #CS frame: ``rotation`` (columns = programmed axes in machine coordinates) and ``origin`` (mm).

    ``to_machine(p) = origin + R·p``; ``to_programmed(q) = Rᵀ·(q − origin)``. The translation is
    applied in the machine system (ISG #CS: offset, then rotation about the offset origin).
    """

    rotation: np.ndarray
    origin: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "rotation", check_rotation(self.rotation))
        o = np.asarray(self.origin, dtype=float).reshape(3)
        if not np.all(np.isfinite(o)):
            raise ValueError(f"frame origin must be finite, got {self.origin!r}")
        object.__setattr__(self, "origin", o)

    @classmethod
    def identity(cls) -> "Frame":
        return cls(np.eye(3), np.zeros(3))

    @classmethod
    def from_cs(cls, x: float = 0.0, y: float = 0.0, z: float = 0.0, a_deg: float = 0.0,
                b_deg: float = 0.0, c_deg: float = 0.0,
                sequence: str = DEFAULT_ROTATION_SEQUENCE) -> "Frame":
        """The frame of ``#CS ON [x, y, z, a, b, c]`` (mm, degrees)."""
        return cls(cs_rotation(a_deg, b_deg, c_deg, sequence), np.array([x, y, z], dtype=float))

    @property
    def z_axis(self) -> np.ndarray:
        """Programmed Z in machine coordinates (``R[:, 2]``), the PCS compensation direction."""
        return self.rotation[:, 2].copy()

    def to_machine(self, p: ArrayLike) -> np.ndarray:
        return self.origin + np.asarray(p, dtype=float) @ self.rotation.T

    def to_programmed(self, q: ArrayLike) -> np.ndarray:
        return (np.asarray(q, dtype=float) - self.origin) @ self.rotation

    def direction_to_machine(self, v: ArrayLike) -> np.ndarray:
        return np.asarray(v, dtype=float) @ self.rotation.T

    def direction_to_programmed(self, v: ArrayLike) -> np.ndarray:
        return np.asarray(v, dtype=float) @ self.rotation

    def then(self, inner: "Frame") -> "Frame":
        """Nested frame: ``inner`` given in this frame's coordinates -> one frame in machine coordinates."""
        return Frame(self.rotation @ inner.rotation, self.to_machine(inner.origin))

    def inverse(self) -> "Frame":
        return Frame(self.rotation.T, -self.origin @ self.rotation)

    def __repr__(self) -> str:  # compact, angles for the default sequence
        a, b, c = cs_angles_from_rotation(self.rotation)
        return f"Frame(origin={self.origin.tolist()}, A={a:.6g}°, B={b:.6g}°, C={c:.6g}° (ZYX))"
