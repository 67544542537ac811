"""Kinematic transformation ID 98: minimum-distance monitoring by a virtual tool extension.

FCT-M3 §12.4.2 (table "Offset data of kinematics", Fig. 44), §12.4.2.1/§12.4.2.2, §12.5, §12.9;
PROG #DIST CTRL example 2; SPEC §11 and §12 (PROG #DIST CTRL's values are the correct 1e-4 units).

Parameters (``V.G.KIN_STEP[1].ID[98].PARAM[i]``):

====  ========  =================================================================  ===========
HD    PARAM[i]  meaning                                                            unit
====  ========  =================================================================  ===========
HD1   0         offset tool clamping point -> tool head reference point            1e-4 mm
HD2   1         inclination from which the head distance to the surface is kept    1e-4 °
HD3   2         inclination up to which it is kept (end of the tool extension)     1e-4 °
HD4   3         maximum inclination; beyond it: error and program abort            1e-4 °
====  ========  =================================================================  ===========

Virtual tool length (SPEC §11), ``θ`` the inclination (:func:`~distctrl.kinematics.inclination`)::

    Lv = L                          θ <  HD2        phase 1: tool length constant
    Lv = L·cos(HD2)/cos(θ)          HD2 ≤ θ ≤ HD3   phase 2: clamping-point height L·cos(HD2) constant
    Lv = L·cos(HD2)/cos(HD3)        θ >  HD3        extension stops
    θ > HD4                         error 900020, program abort

i.e. ``Lv = L·k(θ)`` with the extension factor ``k(θ) = cos(HD2)/cos(clip(θ, HD2, HD3))``
(``k = 1`` when HD2 = HD3). It depends on the inclination only, not on the C orientation
(§12.4.2.2).

Validation (decision, docs/kinematics.md): ``0 ≤ HD2 ≤ 90°``; ``HD2 ≤ HD3``, and ``HD3 < 90°``
unless HD3 = HD2 (no extension band; the factor cos HD2/cos HD3 must be finite);
``HD3 ≤ HD4 ≤ 180°``. HD4 may exceed 90°: both documents' examples use HD4 = 91°.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ErrorId, ParameterError

__all__ = ["Kinematic98Params", "InclinationViolation", "KIN98_MAX_INCLINATION_EXCEEDED",
           "KIN98_PARAM_KEYS", "RAW_LENGTH_PER_MM", "RAW_ANGLE_PER_DEG", "orthogonal_set_distance"]

#: Project error ID (SPEC §7: undocumented errors get IDs >= 900000): inclination θ > HD4 with
#: kinematic 98 active — the documents say "error message with program abort" without a number.
KIN98_MAX_INCLINATION_EXCEEDED = int(ErrorId.KIN98_MAX_INCLINATION)    # 900020

#: The NC variable names of the four parameters (used in error messages).
KIN98_PARAM_KEYS = tuple(f"V.G.KIN_STEP[1].ID[98].PARAM[{i}]" for i in range(4))
_HD = ("HD1", "HD2", "HD3", "HD4")

RAW_LENGTH_PER_MM = 10_000    # PARAM[0] unit 1e-4 mm
RAW_ANGLE_PER_DEG = 10_000    # PARAM[1..3] unit 1e-4 °

_RIGHT = math.pi / 2
_HALF_TURN = math.pi


def _deg(x: float) -> str:
    return f"{math.degrees(x):.4f}°"


def _bad(i: int, value: float, allowed: str, why: str, unit: str = "deg") -> ParameterError:
    shown = _deg(value) if unit == "deg" else f"{value:g} mm"
    return ParameterError(f"{KIN98_PARAM_KEYS[i]} ({_HD[i]}) = {shown}: {why}; allowed: {allowed}",
                          key=KIN98_PARAM_KEYS[i], param_id=_HD[i], value=value, allowed=allowed)


@dataclass(frozen=True)
class InclinationViolation:
    """Description of the error "inclination θ > HD4" (FCT-M3 §12.4.2: error message, program abort).

    A value, not an exception: the caller (the channel / NC runtime) aborts the program with it.
    """

    theta_rad: float
    hd4_rad: float
    id: int = KIN98_MAX_INCLINATION_EXCEEDED
    severity: str = "error"

    @property
    def message(self) -> str:
        return (f"Tool inclination {_deg(self.theta_rad)} exceeds the kinematic-98 maximum inclination "
                f"HD4 = {_deg(self.hd4_rad)} ({KIN98_PARAM_KEYS[3]}); program aborted")

    def __str__(self) -> str:
        return f"{self.severity} {self.id}: {self.message}"


@dataclass(frozen=True)
class Kinematic98Params:
    """Kinematic-98 parameters in internal units (mm, rad); validated on construction.

    Build from the NC values with :meth:`from_raw` (1e-4 mm / 1e-4 °, PROG #DIST CTRL) or from
    degrees with :meth:`from_degrees`.
    """

    hd1_mm: float
    hd2_rad: float
    hd3_rad: float
    hd4_rad: float

    def __post_init__(self) -> None:
        vals = (self.hd1_mm, self.hd2_rad, self.hd3_rad, self.hd4_rad)
        for i, v in enumerate(vals):
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) \
                    or not math.isfinite(float(v)):
                raise ParameterError(f"{KIN98_PARAM_KEYS[i]} ({_HD[i]}) = {v!r}: not a finite number",
                                     key=KIN98_PARAM_KEYS[i], param_id=_HD[i], value=v,
                                     allowed="a finite number")
            object.__setattr__(self, ("hd1_mm", "hd2_rad", "hd3_rad", "hd4_rad")[i], float(v))
        hd2, hd3, hd4 = self.hd2_rad, self.hd3_rad, self.hd4_rad
        if not 0.0 <= hd2 <= _RIGHT:
            raise _bad(1, hd2, "0° <= HD2 <= 90°", "start angle of the tool extension out of range")
        if hd3 < hd2:
            raise _bad(2, hd3, f"HD2 ({_deg(hd2)}) <= HD3 < 90°", "end angle below the start angle HD2")
        if hd3 > hd2 and hd3 >= _RIGHT:
            raise _bad(2, hd3, f"HD2 ({_deg(hd2)}) <= HD3 < 90° (or HD3 = HD2: no extension)",
                       "the extension L·cos(HD2)/cos(HD3) would be infinite")
        if not hd3 <= hd4 <= _HALF_TURN:
            raise _bad(3, hd4, f"HD3 ({_deg(hd3)}) <= HD4 <= 180°",
                       "maximum inclination below HD3 or above 180°")

    # --- construction at the edges --------------------------------------------------------------
    @classmethod
    def from_raw(cls, param0: float, param1: float, param2: float, param3: float) -> "Kinematic98Params":
        """From ``V.G.KIN_STEP[1].ID[98].PARAM[0..3]`` in 1e-4 mm / 1e-4 ° (PROG #DIST CTRL, FCT-M3 §12.4.2).

        ``hd1 = PARAM[0] / 10000`` mm, ``hdk = radians(PARAM[k-1] / 10000)``; dividing by the integer
        10000 is exact for the documented values (1000000 -> 100.0 mm, 300000 -> 30.0°).
        """
        raw = (param0, param1, param2, param3)
        for i, v in enumerate(raw):
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) \
                    or not math.isfinite(float(v)):
                raise ParameterError(f"{KIN98_PARAM_KEYS[i]} ({_HD[i]}) = {v!r}: not a finite number",
                                     key=KIN98_PARAM_KEYS[i], param_id=_HD[i], value=v,
                                     allowed="a finite number (1e-4 mm / 1e-4 °)")
        return cls(float(param0) / RAW_LENGTH_PER_MM,
                   math.radians(float(param1) / RAW_ANGLE_PER_DEG),
                   math.radians(float(param2) / RAW_ANGLE_PER_DEG),
                   math.radians(float(param3) / RAW_ANGLE_PER_DEG))

    @classmethod
    def from_degrees(cls, hd1_mm: float, hd2_deg: float, hd3_deg: float, hd4_deg: float) -> "Kinematic98Params":
        return cls(float(hd1_mm), math.radians(hd2_deg), math.radians(hd3_deg), math.radians(hd4_deg))

    def to_raw(self) -> tuple[int, int, int, int]:
        """Back to the NC values (1e-4 mm / 1e-4 °), rounded to the nearest unit."""
        return (round(self.hd1_mm * RAW_LENGTH_PER_MM),
                round(math.degrees(self.hd2_rad) * RAW_ANGLE_PER_DEG),
                round(math.degrees(self.hd3_rad) * RAW_ANGLE_PER_DEG),
                round(math.degrees(self.hd4_rad) * RAW_ANGLE_PER_DEG))

    # --- the law ----------------------------------------------------------------------------------
    def extension_factor(self, theta: ArrayLike) -> Any:
        """``k(θ) = cos(HD2)/cos(clip(|θ|, HD2, HD3))`` (1 when HD2 = HD3); ``Lv = L·k(θ)``.

        ``k`` is continuous (exactly 1 at and below HD2, constant from HD3 on), non-decreasing in
        ``|θ|``, and ``k·cos θ = cos HD2`` inside the band (constant clamping-point height, §12.4.2
        phase 2). ``θ`` is the inclination; a signed angle (e.g. A = −45°) is taken by magnitude.
        """
        th = np.abs(np.asarray(theta, dtype=float))
        if not np.all(np.isfinite(th)):
            raise ValueError(f"inclination must be finite, got {theta!r}")
        if self.hd3_rad == self.hd2_rad:
            k = np.ones_like(th)
        else:
            k = math.cos(self.hd2_rad) / np.cos(np.clip(th, self.hd2_rad, self.hd3_rad))
        return float(k) if k.ndim == 0 else k

    @property
    def max_extension_factor(self) -> float:
        """``cos(HD2)/cos(HD3)``: the factor from HD3 on (1 when HD2 = HD3)."""
        return 1.0 if self.hd3_rad == self.hd2_rad else math.cos(self.hd2_rad) / math.cos(self.hd3_rad)

    def virtual_tool_length(self, tool_length: ArrayLike, theta: ArrayLike) -> Any:
        """Virtual tool length ``Lv(L, θ)`` (SPEC §11; FCT-M3 §12.4.2, §12.5 ``virt_tool_length_r``).

        ``L`` in mm (``≥ 0``), ``θ`` in rad. Vectorised (numpy broadcasting).
        """
        L = np.asarray(tool_length, dtype=float)
        if not np.all(np.isfinite(L)) or np.any(L < 0):
            raise ValueError(f"tool length must be finite and >= 0, got {tool_length!r}")
        out = L * np.asarray(self.extension_factor(theta))
        return float(out) if out.ndim == 0 else out

    def exceeds_max_inclination(self, theta: ArrayLike) -> Any:
        """``|θ| > HD4`` (vectorised boolean)."""
        out = np.abs(np.asarray(theta, dtype=float)) > self.hd4_rad
        return bool(out) if out.ndim == 0 else out

    def check_inclination(self, theta: float) -> InclinationViolation | None:
        """``None`` if ``|θ| ≤ HD4``, else the error description (ID 900020; the program aborts).

        FCT-M3 §12.4.2: "HD4: Maximum inclination angle. When exceeded, an error message is
        output with process abort." Exactly HD4 is still allowed. A non-finite θ is a violation too.
        """
        th = abs(float(theta))
        if math.isfinite(th) and th <= self.hd4_rad:
            return None
        return InclinationViolation(th, self.hd4_rad)


def orthogonal_set_distance(set_dist: ArrayLike, theta: ArrayLike,
                            kin98: Kinematic98Params | None = None) -> Any:
    """Orthogonal set distance of the clamping point for a tool inclined by ``θ`` (SPEC §11, §12.9).

    ``SET_DIST·cos θ`` without kinematic 98; with it the set distance (= tool length, §12.1.2) is
    virtually extended: ``SET_DIST·k(θ)·cos θ`` (``= SET_DIST·cos HD2`` for HD2 ≤ θ ≤ HD3).
    ``θ`` is the angle between the tool and the surface normal (= the inclination on a horizontal
    workpiece).
    """
    th = np.asarray(theta, dtype=float)
    out = np.asarray(set_dist, dtype=float) * np.cos(th)
    if kin98 is not None:
        out = out * np.asarray(kin98.extension_factor(th))
    return float(out) if out.ndim == 0 else out
