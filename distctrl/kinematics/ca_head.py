"""5-axis CA head with RTCP: tool direction, inverse orientation, pivot <-> TCP (mm, rad).

SPEC §11; FCT-M3 §12.1.2 ("Constant tool centre point", Fig. 38), §12.4.1, §12.4.2.1
("Inclination of tool via CA kinematic", Fig. 45), §12.4.2.2 (orientations in the plane).

Kinematics (fixed by SPEC §11): C rotates about machine Z, A about X; the tool direction
(TCP -> head, away from the workpiece) is

    u(C, A) = R_z(C)·R_x(A)·(0, 0, 1) = (sin C·sin A, −cos C·sin A, cos A)

and the inclination is ``θ = arccos(u_z) = |A|``. With the TCP kept (RTCP) the pivot (head
reference point, whose position the linear axes X, Y, Z carry) is

    pivot = TCP + (L + HD1)·u

(``L`` tool length TCP -> clamping point, ``HD1`` clamping point -> head reference, kinematic-98
PARAM[0]). With kinematic 98 active ``L`` is replaced by the virtual length ``Lv(θ)``. Keeping the
TCP while the tool inclines therefore moves the pivot on a sphere of radius ``L + HD1`` around it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from .geometry import _out, clamping_point, inclination, unit
from .kin98 import Kinematic98Params

__all__ = ["ca_tool_direction", "ca_angles_from_direction", "CaHeadRtcp", "CaAxes", "SINGULAR_TOL"]

#: ``sqrt(u_x² + u_y²)`` at or below this is the singular orientation (tool along ±Z): C is free.
SINGULAR_TOL = 1e-12
_TWO_PI = 2.0 * math.pi


def ca_tool_direction(c: ArrayLike, a: ArrayLike) -> np.ndarray:
    """Unit tool direction of the CA head: ``u = (sin C·sin A, −cos C·sin A, cos A)`` (SPEC §11).

    ``c``, ``a`` in rad, broadcast against each other; the result has shape ``(..., 3)``
    (``(3,)`` for scalars). ``|u| = 1`` by construction; ``inclination(u) = |A|`` for |A| ≤ π.
    """
    c = np.asarray(c, dtype=float)
    a = np.asarray(a, dtype=float)
    sa = np.sin(a)
    return np.stack(np.broadcast_arrays(np.sin(c) * sa, -np.cos(c) * sa, np.cos(a)), axis=-1)


def ca_angles_from_direction(u: ArrayLike, c_hint: ArrayLike | None = None) -> tuple[Any, Any]:
    """Inverse of :func:`ca_tool_direction`: the axis angles ``(C, A)`` for a tool direction.

    ``u`` need not be normalised. Branch (decision, docs/kinematics.md):

    * ``A = atan2(sqrt(u_x² + u_y²), u_z) ∈ [0, π]`` — the branch ``A ≥ 0``. (The other solution
      is ``(C + π, −A)``; e.g. PROG #DIST CTRL's ``A=-45°, C=0`` is returned as ``A=45°, C=180°``.)
    * ``C = atan2(u_x, −u_y) + 2πk`` with ``k`` chosen so that ``C`` is closest to ``c_hint``
      (``|C − c_hint| ≤ π``); without a hint ``C ∈ (−π, π]``.
    * Singular orientation (``sqrt(u_x² + u_y²) ≤ SINGULAR_TOL``, tool along +Z or −Z): ``C`` is
      undetermined and keeps ``c_hint`` (0 without a hint), so an upright tool never spins C.

    Vectorised over ``u[..., 3]`` and ``c_hint``; scalars come back as floats.
    """
    u = unit(u, name="tool direction u")
    ux, uy, uz = u[..., 0], u[..., 1], u[..., 2]
    s = np.hypot(ux, uy)
    a = np.arctan2(s, uz)
    c0 = np.arctan2(ux, -uy)
    if c_hint is None:
        hint = np.zeros_like(c0)
        c = c0
    else:
        hint = np.asarray(c_hint, dtype=float)
        if not np.all(np.isfinite(hint)):
            raise ValueError(f"c_hint must be finite, got {c_hint!r}")
        c = c0 + _TWO_PI * np.rint((hint - c0) / _TWO_PI)
    c = np.where(s <= SINGULAR_TOL, hint, c)
    c, a = np.broadcast_arrays(c, a)
    return _out(c), _out(a)


class CaAxes(NamedTuple):
    """Machine axis values of the CA head: pivot position X, Y, Z (mm) and C, A (rad)."""

    x: Any
    y: Any
    z: Any
    c: Any
    a: Any


@dataclass(frozen=True)
class CaHeadRtcp:
    """CA head with RTCP (TCP kept constant while the tool inclines, FCT-M3 §12.1.2).

    ``tool_length`` ``L`` (mm, TCP -> clamping point; = SET_DIST, §12.1.2), ``hd1`` (mm, clamping
    point -> head reference point/pivot), optionally ``kin98`` (then ``L`` becomes ``Lv(θ)`` and
    ``hd1`` must equal ``kin98.hd1_mm``; build it with :meth:`with_kin98`).
    """

    tool_length: float
    hd1: float = 0.0
    kin98: Kinematic98Params | None = None

    def __post_init__(self) -> None:
        for name in ("tool_length", "hd1"):
            v = getattr(self, name)
            if isinstance(v, bool) or not math.isfinite(float(v)):
                raise ValueError(f"{name} must be a finite number, got {v!r}")
            object.__setattr__(self, name, float(v))
        if self.tool_length < 0:
            raise ValueError(f"tool_length must be >= 0, got {self.tool_length!r}")
        if self.kin98 is not None and self.kin98.hd1_mm != self.hd1:
            raise ValueError(f"hd1 ({self.hd1} mm) differs from kinematic-98 HD1 ({self.kin98.hd1_mm} mm); "
                             "use CaHeadRtcp.with_kin98(tool_length, params)")

    @classmethod
    def with_kin98(cls, tool_length: float, params: Kinematic98Params) -> "CaHeadRtcp":
        """Head with kinematic 98 active: ``hd1`` from PARAM[0], virtual length from HD2/HD3."""
        return cls(tool_length, params.hd1_mm, params)

    # --- lengths ------------------------------------------------------------------------------------
    def effective_tool_length(self, theta: ArrayLike) -> Any:
        """``L``, or ``Lv(L, θ)`` with kinematic 98 (SPEC §11)."""
        if self.kin98 is None:
            th = np.asarray(theta, dtype=float)
            return _out(np.full(th.shape, self.tool_length))
        return self.kin98.virtual_tool_length(self.tool_length, theta)

    def pivot_distance(self, theta: ArrayLike) -> Any:
        """``|pivot − TCP| = L_eff(θ) + HD1`` (radius of the pivot sphere without kinematic 98)."""
        return _out(np.asarray(self.effective_tool_length(theta)) + self.hd1)

    def _u_len(self, c: ArrayLike, a: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        u = ca_tool_direction(c, a)
        r = np.asarray(self.pivot_distance(inclination(u)))
        return u, r

    # --- forward / inverse --------------------------------------------------------------------------
    def pivot_from_tcp(self, tcp_xyz: ArrayLike, c: ArrayLike, a: ArrayLike) -> np.ndarray:
        """Machine X, Y, Z (pivot) for a TCP and orientation: ``TCP + (L_eff + HD1)·u(C, A)``."""
        u, r = self._u_len(c, a)
        return np.asarray(tcp_xyz, dtype=float) + r[..., None] * u

    def tcp_from_pivot(self, pivot_xyz: ArrayLike, c: ArrayLike, a: ArrayLike) -> np.ndarray:
        """TCP from machine X, Y, Z (pivot) and C, A: ``pivot − (L_eff + HD1)·u(C, A)``."""
        u, r = self._u_len(c, a)
        return np.asarray(pivot_xyz, dtype=float) - r[..., None] * u

    def clamping_point(self, tcp_xyz: ArrayLike, c: ArrayLike, a: ArrayLike) -> np.ndarray:
        """Tool clamping point (laser exit) ``TCP + L_eff·u`` (FCT-M3 §12.4.1)."""
        u = ca_tool_direction(c, a)
        return clamping_point(tcp_xyz, u, self.effective_tool_length(inclination(u)))

    def clamping_point_distance(self, tcp_xyz: ArrayLike, c: float, a: float, surface: Any) -> float:
        """Orthogonal distance of the clamping point to ``surface`` (a :class:`Plane`/:class:`HeightField`).

        The idealised sensor value of FCT-M3 §12.3.
        """
        return surface.orthogonal_distance(self.clamping_point(tcp_xyz, c, a))

    def machine_axes(self, tcp_xyz: ArrayLike, u: ArrayLike, c_hint: ArrayLike | None = None) -> CaAxes:
        """RTCP inverse kinematics: axis values ``(X, Y, Z, C, A)`` for a TCP and a tool direction.

        ``(C, A)`` from :func:`ca_angles_from_direction` (branch A ≥ 0, C nearest ``c_hint``), then
        the pivot from :meth:`pivot_from_tcp`.
        """
        c, a = ca_angles_from_direction(u, c_hint)
        p = self.pivot_from_tcp(tcp_xyz, c, a)
        return CaAxes(_out(p[..., 0]), _out(p[..., 1]), _out(p[..., 2]), c, a)

    def tcp_from_axes(self, axes: CaAxes | tuple) -> np.ndarray:
        """TCP from axis values ``(X, Y, Z, C, A)`` (forward kinematics)."""
        x, y, z, c, a = axes
        pivot = np.stack(np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (x, y, z))), axis=-1)
        return self.tcp_from_pivot(pivot, c, a)
