"""Direction of the 3D distance-control compensation for each MODE, and its orthogonal effect.

SPEC §11; FCT-M3 §12.1.3 (Fig. 40/41), §12.2 (``MODE=``, ``DIRECTION=``), §12.4.3 with the
examples §12.4.3.1 (compensation in tool direction), §12.4.3.2 (orthogonal to the surface, i.e. in
Z) and §12.4.3.3 (robot, workpiece inclined by 30° in the PCS); PROG #DIST CTRL.

The offset ``δ`` (mm, positive = lifting, away from the workpiece, SPEC §1) is superimposed as the
vector ``δ·e`` with the unit direction ``e``:

=====  ==========================================================================================
MODE   ``e``
=====  ==========================================================================================
ACS    machine Z axis ``(0, 0, 1)`` (DIRECTION=Z; on the physical Z axis, as the axis variant).
       For the CA head the Z axis is parallel to machine Z, so the vector is the same as MCS.
MCS    machine Z ``(0, 0, 1)``: the XY projection of the contour stays (§12.1.3 "Projection in
       X/Y remains stationary"; §12.4.3 item 2).
PCS    programmed Z: ``R·(0, 0, 1) = R[:, 2]`` with ``R`` the active #CS rotation (identity if none).
ECS    the tool direction ``û`` (§12.4.3 item 1: cutting-curve orientation kept); needs kinematic
       98 active (#KIN ID[98], #TRAFO ON) — checked by the caller, not here.
OFF    no superposition (the default): the zero vector, so ``δ·e = 0``.
=====  ==========================================================================================

Only DIRECTION=Z exists (X/Y "in preparation", §12.2), so no axis argument is taken.

The orthogonal distance to a surface with unit normal ``n`` changes by ``δ·(e·n)``: on a horizontal
surface ECS gives ``δ·cos θ`` (SPEC §11), MCS/ACS give ``δ``.
"""
from __future__ import annotations

from enum import Enum
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .frames import Frame, check_rotation
from .geometry import _out, unit

__all__ = ["CompensationMode", "compensation_direction", "compensation_vector", "orthogonal_change"]

_Z = np.array([0.0, 0.0, 1.0])


class CompensationMode(str, Enum):
    """``#DIST CTRL [MODE=..]`` identifiers (FCT-M3 §12.2)."""

    OFF = "OFF"
    ACS = "ACS"
    MCS = "MCS"
    PCS = "PCS"
    ECS = "ECS"

    @classmethod
    def parse(cls, value: "CompensationMode | str") -> "CompensationMode":
        if isinstance(value, cls):
            return value
        try:
            return cls(str(value).strip().upper())
        except ValueError:
            raise ValueError(f"MODE={value!r} unknown; allowed: {', '.join(m.value for m in cls)}") from None


def compensation_direction(mode: CompensationMode | str, u: ArrayLike | None = None,
                           cs_rotation: ArrayLike | Frame | None = None) -> np.ndarray:
    """Unit direction ``e`` along which the offset is superimposed (table in the module docstring).

    ``u`` is the tool direction (needed for ECS only; normalised here; may be ``(..., 3)``).
    ``cs_rotation`` is the active #CS rotation matrix (or a :class:`Frame`), used by PCS only.
    OFF returns the zero vector (no superposition).
    """
    m = CompensationMode.parse(mode)
    if m is CompensationMode.ECS:
        if u is None:
            raise ValueError("MODE=ECS needs the tool direction u")
        return unit(u, name="tool direction u")
    if m is CompensationMode.PCS:
        if cs_rotation is None:
            return _Z.copy()
        r = cs_rotation.rotation if isinstance(cs_rotation, Frame) else check_rotation(cs_rotation)
        return r[:, 2].copy()
    if m is CompensationMode.OFF:
        return np.zeros(3)
    return _Z.copy()  # ACS (DIRECTION=Z) and MCS


def compensation_vector(mode: CompensationMode | str, delta: ArrayLike, u: ArrayLike | None = None,
                        cs_rotation: ArrayLike | Frame | None = None) -> np.ndarray:
    """The superimposed motion ``δ·e`` (mm) of TCP and head; the orientation is unchanged."""
    e = compensation_direction(mode, u, cs_rotation)
    return np.asarray(delta, dtype=float)[..., None] * e


def orthogonal_change(delta: ArrayLike, direction: ArrayLike, surface_normal: ArrayLike) -> Any:
    """Change of the orthogonal distance caused by ``δ`` along ``direction``: ``δ·(ê·n̂)``.

    Both vectors are normalised (a zero ``direction`` — MODE OFF — gives 0). For ECS on a plane
    with normal Z this is ``δ·cos θ`` (SPEC §11); for MCS on a horizontal plane ``δ``; for MCS on a
    workpiece inclined by α (FCT-M3 §12.4.3.3) ``δ·cos α``.
    """
    d = np.asarray(direction, dtype=float)
    norm = np.linalg.norm(d, axis=-1, keepdims=True)
    if not np.all(np.isfinite(d)):
        raise ValueError(f"direction must be finite, got {direction!r}")
    e = np.where(norm > 0, d / np.where(norm > 0, norm, 1.0), 0.0)
    n = unit(surface_normal, name="surface normal")
    return _out(np.asarray(delta, dtype=float) * np.sum(e * n, axis=-1))
