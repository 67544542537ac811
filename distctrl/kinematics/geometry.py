"""Vectors, tool inclination, workpiece surfaces and distances (mm, rad).

Conventions (SPEC §1, §11; docs/kinematics.md):

* Machine coordinates, right-handed, **Z points away from the workpiece**. A surface normal points
  out of the material (towards the tool), so a point above the surface has a *positive* signed
  orthogonal distance.
* The tool direction ``u`` is the unit vector from the tool centre point (TCP) *towards the head*
  (TCP -> clamping point -> pivot), i.e. it points away from the workpiece like Z. An upright tool
  has ``u = (0, 0, 1)``.
* Everything is vectorised over leading axes where natural: a point or vector is an array of shape
  ``(..., 3)``; scalar results of a single input are returned as Python ``float``.

Sources: FCT-M3 §12.1.2 (constant TCP), §12.3 (the sensor value is the orthogonal distance of
the tool clamping point, the laser exit, to the surface), §12.4.1 (Fig. 43, distance to the
workpiece surface); SPEC §11.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["unit", "inclination", "angle_between", "orthogonal_distance", "distance_along",
           "surface_normal", "Plane", "HeightField", "clamping_point", "clamping_point_distance",
           "PARALLEL_TOL"]

#: |n·d| below this (unit vectors) counts as "ray parallel to the plane": no intersection (NaN).
PARALLEL_TOL = 1e-12


def _out(x: np.ndarray) -> Any:
    """A 0-d result as Python float, anything else unchanged."""
    x = np.asarray(x)
    return float(x) if x.ndim == 0 else x


def unit(v: ArrayLike, *, name: str = "vector") -> np.ndarray:
    """``v / |v|`` along the last axis (shape ``(..., 3)``).

    Raises ``ValueError`` for a zero-length or non-finite vector (a direction must be defined).
    """
    v = np.asarray(v, dtype=float)
    if v.shape[-1:] != (3,):
        raise ValueError(f"{name} must have shape (..., 3), got {v.shape}")
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    if not np.all(np.isfinite(v)) or np.any(n == 0.0):
        raise ValueError(f"{name} must be finite and non-zero, got {v.tolist()}")
    return v / n


def inclination(u: ArrayLike) -> Any:
    """Inclination ``θ`` of the tool direction ``u`` against machine +Z, in ``[0, π]`` rad.

    ``θ = arccos(u_z / |u|)`` (SPEC §11), computed as ``atan2(sqrt(u_x² + u_y²), u_z)``, which is
    the same angle but accurate near 0 and π. For the CA head ``θ = |A|`` (|A| ≤ π).
    This is the angle reported to the PLC as ``bahn_state.inclination_r`` (FCT-M3 §12.5) and
    the one kinematic 98 monitors (FCT-M3 §12.4.2).
    """
    u = unit(u, name="tool direction u")
    return _out(np.arctan2(np.hypot(u[..., 0], u[..., 1]), u[..., 2]))


def angle_between(u: ArrayLike, n: ArrayLike) -> Any:
    """Angle between two directions in ``[0, π]``: ``atan2(|u × n|, u · n)``.

    With ``n`` a surface normal this is the tool's inclination *to the surface* (for an inclined
    workpiece, FCT-M3 §12.4.3.3, it differs from :func:`inclination`).
    """
    u = unit(u, name="u")
    n = unit(n, name="n")
    return _out(np.arctan2(np.linalg.norm(np.cross(u, n), axis=-1), np.sum(u * n, axis=-1)))


def orthogonal_distance(point: ArrayLike, plane_point: ArrayLike, plane_normal: ArrayLike) -> Any:
    """Signed orthogonal distance of ``point`` to the plane ``(plane_point, plane_normal)``.

    ``d = n̂ · (p − p0)``; positive on the side the normal points to (above the workpiece).
    FCT-M3 §12.3/§12.4.1: the sensor value is this distance for the tool clamping point.
    """
    n = unit(plane_normal, name="plane normal")
    p = np.asarray(point, dtype=float)
    p0 = np.asarray(plane_point, dtype=float)
    return _out(np.sum(n * (p - p0), axis=-1))


def distance_along(point: ArrayLike, direction: ArrayLike, plane_point: ArrayLike,
                   plane_normal: ArrayLike) -> Any:
    """Signed distance ``t`` from ``point`` along ``direction`` to the plane (ray/plane intersection).

    ``p + t·d̂`` lies on the plane: ``t = n̂ · (p0 − p) / (n̂ · d̂)`` with ``d̂`` normalised, so ``t``
    is a length in mm (negative: the plane lies behind the point). NaN when the ray is parallel to
    the plane (``|n̂·d̂| < PARALLEL_TOL``). Example: from the clamping point along ``−u`` to the
    surface is the beam length, ``L`` when the TCP lies on the surface (FCT-M3 §12.4.1).
    """
    n = unit(plane_normal, name="plane normal")
    d = unit(direction, name="direction")
    p = np.asarray(point, dtype=float)
    p0 = np.asarray(plane_point, dtype=float)
    den = np.sum(n * d, axis=-1)
    num = np.sum(n * (p0 - p), axis=-1)
    parallel = np.abs(den) < PARALLEL_TOL
    t = np.where(parallel, np.nan, num / np.where(parallel, 1.0, den))
    return _out(t)


def surface_normal(fx: ArrayLike, fy: ArrayLike) -> np.ndarray:
    """Unit normal of ``z = f(x, y)`` from its slopes: ``(−f_x, −f_y, 1) / sqrt(1 + f_x² + f_y²)``.

    Points up (+Z, out of the material), SPEC §1.
    """
    fx = np.asarray(fx, dtype=float)
    fy = np.asarray(fy, dtype=float)
    v = np.stack(np.broadcast_arrays(-fx, -fy, np.ones_like(fx + fy)), axis=-1)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@dataclass(frozen=True, eq=False)
class Plane:
    """A plane surface: a point on it and its unit normal (normalised on construction).

    The normal points out of the material (towards the tool). An inclined workpiece programmed in a
    rotated #CS (FCT-M3 §12.4.3.3 "Robot", 30°) is ``Plane.from_frame(frame)``.
    """

    point: np.ndarray
    normal: np.ndarray

    def __post_init__(self) -> None:
        p = np.asarray(self.point, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f"plane point must be 3 finite numbers, got {self.point!r}")
        object.__setattr__(self, "point", p)
        object.__setattr__(self, "normal", unit(np.asarray(self.normal, dtype=float).reshape(3),
                                                name="plane normal"))

    @classmethod
    def horizontal(cls, z: float = 0.0) -> "Plane":
        """The plane ``Z = z`` with normal +Z."""
        return cls(np.array([0.0, 0.0, float(z)]), np.array([0.0, 0.0, 1.0]))

    @classmethod
    def from_frame(cls, frame: Any) -> "Plane":
        """The programmed XY plane of a #CS frame (origin, normal = programmed Z in machine coordinates)."""
        return cls(np.asarray(frame.origin, dtype=float), np.asarray(frame.z_axis, dtype=float))

    def normal_at(self, point: ArrayLike | None = None) -> np.ndarray:
        return self.normal.copy()

    def orthogonal_distance(self, point: ArrayLike) -> Any:
        """:func:`orthogonal_distance` to this plane."""
        return orthogonal_distance(point, self.point, self.normal)

    def distance_along(self, point: ArrayLike, direction: ArrayLike) -> Any:
        """:func:`distance_along` to this plane."""
        return distance_along(point, direction, self.point, self.normal)

    def foot_point(self, point: ArrayLike) -> np.ndarray:
        """Orthogonal projection of ``point`` onto the plane: ``p − d·n̂``."""
        p = np.asarray(point, dtype=float)
        d = np.asarray(self.orthogonal_distance(p))
        return p - d[..., None] * self.normal


@dataclass(frozen=True, eq=False)
class HeightField:
    """A surface ``z = f(x, y)`` with its normal ``(−f_x, −f_y, 1)/|·|``.

    ``f(x, y) -> z`` and optionally ``gradient(x, y) -> (f_x, f_y)``; without a gradient, central
    differences with step ``step`` (mm) are used. Duck-compatible with ``distctrl.sim.surface``
    objects: ``HeightField.from_surface(s)`` uses ``s.z``/``s.height`` and ``s.gradient``.

    Scalar per point (not vectorised): the foot point and the ray intersection are iterations.
    """

    f: Callable[[float, float], float]
    gradient: Callable[[float, float], tuple[float, float]] | None = None
    step: float = 1e-6
    tol: float = 1e-12
    max_iter: int = 100

    @classmethod
    def from_surface(cls, surface: Any) -> "HeightField":
        f = getattr(surface, "height", None) or getattr(surface, "z")
        return cls(f, getattr(surface, "gradient", None))

    def height(self, x: float, y: float) -> float:
        return float(self.f(float(x), float(y)))

    def slope(self, x: float, y: float) -> tuple[float, float]:
        """``(∂f/∂x, ∂f/∂y)`` at ``(x, y)``."""
        if self.gradient is not None:
            gx, gy = self.gradient(float(x), float(y))
            return float(gx), float(gy)
        h = self.step
        return ((self.height(x + h, y) - self.height(x - h, y)) / (2 * h),
                (self.height(x, y + h) - self.height(x, y - h)) / (2 * h))

    def normal_at(self, point: ArrayLike) -> np.ndarray:
        """Unit normal at the surface point above/below ``(point[0], point[1])``."""
        x, y = float(point[0]), float(point[1])
        return surface_normal(*self.slope(x, y))

    def vertical_distance(self, point: ArrayLike) -> float:
        """Distance along machine Z: ``p_z − f(p_x, p_y)`` (what an axis-specific Z control sees)."""
        return float(point[2]) - self.height(point[0], point[1])

    def foot_point(self, point: ArrayLike) -> np.ndarray:
        """The surface point nearest to ``point`` (local minimum of ``|p − q|`` from the vertical projection).

        Fixed-point iteration: at ``q = (x, y, f(x, y))`` project ``p`` onto the tangent plane and
        take its ``x, y`` as the next estimate; at the foot point ``p − q`` is parallel to the normal
        and the iteration stands still. It contracts while the distance is smaller than the radius
        of curvature; otherwise a least-squares minimisation finishes the job.
        """
        p = np.asarray(point, dtype=float).reshape(3)
        x, y = p[0], p[1]
        scale = 1.0 + float(np.max(np.abs(p)))
        for _ in range(self.max_iter):
            q = np.array([x, y, self.height(x, y)])
            n = self.normal_at(q)
            proj = p - float(np.dot(n, p - q)) * n
            dx, dy = proj[0] - x, proj[1] - y
            x, y = proj[0], proj[1]
            if math.hypot(dx, dy) <= self.tol * scale:
                return np.array([x, y, self.height(x, y)])
        from scipy.optimize import least_squares  # fallback, rarely needed

        res = least_squares(lambda xy: p - np.array([xy[0], xy[1], self.height(xy[0], xy[1])]),
                            np.array([x, y]), xtol=1e-15, ftol=1e-15, gtol=1e-15)
        return np.array([res.x[0], res.x[1], self.height(res.x[0], res.x[1])])

    def orthogonal_distance(self, point: ArrayLike) -> float:
        """Signed orthogonal distance: ``|p − q|`` with ``q`` the foot point, sign of ``n(q)·(p − q)``."""
        p = np.asarray(point, dtype=float).reshape(3)
        q = self.foot_point(p)
        d = float(np.linalg.norm(p - q))
        return math.copysign(d, float(np.dot(self.normal_at(q), p - q))) if d > 0 else 0.0

    def distance_along(self, point: ArrayLike, direction: ArrayLike) -> float:
        """Signed distance ``t`` along ``direction`` (normalised) to the surface; NaN if none found.

        Solves ``g(t) = p_z + t·d_z − f(p_x + t·d_x, p_y + t·d_y) = 0`` by Newton
        (``g' = d_z − f_x·d_x − f_y·d_y``), starting from the tangent plane below ``p``.
        """
        p = np.asarray(point, dtype=float).reshape(3)
        d = unit(np.asarray(direction, dtype=float).reshape(3), name="direction")
        q0 = np.array([p[0], p[1], self.height(p[0], p[1])])
        t = distance_along(p, d, q0, self.normal_at(q0))
        if not math.isfinite(t):
            t = 0.0
        scale = 1.0 + float(np.max(np.abs(p)))
        for _ in range(self.max_iter):
            r = p + t * d
            g = r[2] - self.height(r[0], r[1])
            if abs(g) <= self.tol * scale:
                return float(t)
            fx, fy = self.slope(r[0], r[1])
            dg = d[2] - fx * d[0] - fy * d[1]
            if abs(dg) < PARALLEL_TOL:
                return math.nan
            t -= g / dg
        return math.nan


def clamping_point(tcp: ArrayLike, u: ArrayLike, tool_length: ArrayLike) -> np.ndarray:
    """Tool clamping point (laser exit): ``TCP + L·û`` (FCT-M3 §12.4.1: tool length = laser length).

    With kinematic 98 pass the virtual tool length ``Lv`` as ``tool_length`` (FCT-M3 §12.5: the
    virtual length is the distance between laser exit and focus point).
    """
    u = unit(u, name="tool direction u")
    L = np.asarray(tool_length, dtype=float)
    return np.asarray(tcp, dtype=float) + L[..., None] * u


def clamping_point_distance(tcp: ArrayLike, u: ArrayLike, tool_length: ArrayLike,
                            plane_point: ArrayLike, plane_normal: ArrayLike) -> Any:
    """Orthogonal distance of the clamping point to a plane: ``n̂ · (TCP + L·û − p0)``.

    This is the idealised sensor value the PLC delivers (FCT-M3 §12.3). With the TCP on the
    surface it is ``L·cos θ_n`` (``θ_n`` the angle between tool and surface normal): the reduction of
    the orthogonal distance by inclination that 3D distance control takes into account (§12.1.2,
    §12.4.1; SPEC §11 "orthogonal set distance SET_DIST·cos θ").
    """
    return orthogonal_distance(clamping_point(tcp, u, tool_length), plane_point, plane_normal)
