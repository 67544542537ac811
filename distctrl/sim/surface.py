"""Workpiece surface model ``z = f(x, y)`` (mm) built from composable features.

A :class:`Surface` is a ``base`` height plus the sum of its features. Every feature is a small
object with

* ``z(x, y) -> float``            scalar height contribution (mm), the fast per-cycle path,
* ``z_array(xs, ys) -> ndarray``  the same, vectorised (numpy broadcasting),
* ``gradient(x, y) -> (dz/dx, dz/dy)`` analytic slope (mm/mm).

Features: :class:`Flat`, :class:`Step` (thickness step or block obstacle), :class:`Ramp`,
:class:`Sine` (waviness), :class:`TiltedPlane`, :class:`Holes` (round holes through the sheet),
:class:`HeightMap` (bilinear grid from CSV).

Z points away from the workpiece (SPEC §1): a larger ``z`` is a higher surface, closer to the head.

Vertical edges (a :class:`Step` with ``ramp_length = 0``) have no defined slope; their gradient is
taken as 0 (the surface normal points straight up on both sides and on the edge itself).
"""
from __future__ import annotations

import bisect
import csv
import math
import os
from typing import Iterable, Protocol, Sequence

import numpy as np

from distctrl.errors.config import (MISSING, ConfigError, require_choice, require_mapping,
                                       require_number)

__all__ = ["Feature", "Flat", "Step", "Ramp", "Sine", "TiltedPlane", "Holes", "HeightMap", "Surface",
           "surface_from_config", "FEATURE_TYPES"]

_TWO_PI = 2.0 * math.pi


class Feature(Protocol):
    def z(self, x: float, y: float) -> float: ...

    def z_array(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray: ...

    def gradient(self, x: float, y: float) -> tuple[float, float]: ...


def _axis(value: object, key: str) -> str:
    """Accept "X"/"Y" in either case; return the upper-case name."""
    if isinstance(value, str) and value.upper() in ("X", "Y"):
        return value.upper()
    return require_choice(value, key, ("X", "Y"))  # raises with the allowed values


def _unit_ramp(u: float, start: float, length: float) -> float:
    """0 below ``start``, 1 from ``start + length`` on, linear between; ``length = 0``: a step that
    takes the upper value exactly at ``start`` (right-continuous)."""
    if length <= 0.0:
        return 1.0 if u >= start else 0.0
    t = (u - start) / length
    return 0.0 if t <= 0.0 else (1.0 if t >= 1.0 else t)


def _unit_ramp_array(u: np.ndarray, start: float, length: float) -> np.ndarray:
    if length <= 0.0:
        return (u >= start).astype(float)
    return np.clip((u - start) / length, 0.0, 1.0)


def _unit_ramp_slope(u: float, start: float, length: float) -> float:
    """d/du of :func:`_unit_ramp` (0 on a vertical edge, 1/length strictly inside the ramp)."""
    if length <= 0.0 or not (start < u < start + length):
        return 0.0
    return 1.0 / length


class Flat:
    """No contribution: the surface is just the base height."""

    def z(self, x: float, y: float) -> float:
        return 0.0

    def z_array(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        return np.zeros(np.broadcast(np.asarray(xs), np.asarray(ys)).shape)

    def gradient(self, x: float, y: float) -> tuple[float, float]:
        return (0.0, 0.0)

    def __repr__(self) -> str:
        return "Flat()"


class Step:
    """Thickness step, or a block obstacle when ``width`` is given.

    Along ``axis`` ("X" or "Y") at coordinate ``u``:

    * without ``width``: 0 for ``u < at``, ``height`` from ``u >= at`` on (the edge itself already
      has the new height). With ``ramp_length > 0`` the edge rises linearly over
      ``[at, at + ramp_length]``.
    * with ``width`` (mm): a block with footprint ``[at, at + width)``, e.g. the 2.8 mm obstacle of
      the documents' filter test. Edges of ``ramp_length`` lie inside the footprint (rising over
      ``[at, at + ramp_length]``, falling over ``[at + width - ramp_length, at + width]``), so
      ``ramp_length <= width / 2``.

    ``height`` (mm) may be negative (a groove or a step down).
    """

    def __init__(self, at: float, height: float, axis: str = "X", width: float | None = None,
                 ramp_length: float = 0.0):
        self.axis = _axis(axis, "Step.axis")
        self.at = require_number(at, "Step.at")
        self.height = require_number(height, "Step.height")
        self.width = None if width is None else require_number(width, "Step.width", lo=0.0, lo_open=True)
        hi = None if self.width is None else self.width / 2.0
        self.ramp_length = require_number(ramp_length, "Step.ramp_length", lo=0.0, hi=hi)
        self._on_y = self.axis == "Y"
        # per-cycle constants: a vertical edge (ramp_length 0) is the comparison of _unit_ramp's first line
        self._vertical = self.ramp_length <= 0.0
        self._fall_at = None if self.width is None else self.at + self.width - self.ramp_length

    def _profile(self, u: float) -> float:
        up = _unit_ramp(u, self.at, self.ramp_length)
        if self.width is None:
            return up
        return up - _unit_ramp(u, self.at + self.width - self.ramp_length, self.ramp_length)

    def z(self, x: float, y: float) -> float:
        u = y if self._on_y else x
        if self._vertical:                      # _profile with _unit_ramp's step, without the calls
            up = 1.0 if u >= self.at else 0.0
            if self._fall_at is None:
                return self.height * up
            return self.height * (up - (1.0 if u >= self._fall_at else 0.0))
        return self.height * self._profile(u)

    def z_array(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        xs, ys = np.broadcast_arrays(np.asarray(xs, float), np.asarray(ys, float))
        u = ys if self._on_y else xs
        p = _unit_ramp_array(u, self.at, self.ramp_length)
        if self.width is not None:
            p = p - _unit_ramp_array(u, self.at + self.width - self.ramp_length, self.ramp_length)
        return self.height * p

    def gradient(self, x: float, y: float) -> tuple[float, float]:
        u = y if self._on_y else x
        s = _unit_ramp_slope(u, self.at, self.ramp_length)
        if self.width is not None:
            s -= _unit_ramp_slope(u, self.at + self.width - self.ramp_length, self.ramp_length)
        g = self.height * s
        return (0.0, g) if self._on_y else (g, 0.0)

    def __repr__(self) -> str:
        return (f"Step(at={self.at!r}, height={self.height!r}, axis={self.axis!r}, width={self.width!r}, "
                f"ramp_length={self.ramp_length!r})")


class Ramp:
    """Linear slope along ``axis``: 0 up to ``start``, ``height`` from ``end`` on (mm), linear between."""

    def __init__(self, start: float, end: float, height: float, axis: str = "X"):
        self.axis = _axis(axis, "Ramp.axis")
        self.start = require_number(start, "Ramp.start")
        self.end = require_number(end, "Ramp.end", lo=self.start, lo_open=True)
        self.height = require_number(height, "Ramp.height")
        self._on_y = self.axis == "Y"
        self._length = self.end - self.start

    def z(self, x: float, y: float) -> float:
        return self.height * _unit_ramp(y if self._on_y else x, self.start, self._length)

    def z_array(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        xs, ys = np.broadcast_arrays(np.asarray(xs, float), np.asarray(ys, float))
        return self.height * _unit_ramp_array(ys if self._on_y else xs, self.start, self._length)

    def gradient(self, x: float, y: float) -> tuple[float, float]:
        g = self.height * _unit_ramp_slope(y if self._on_y else x, self.start, self._length)
        return (0.0, g) if self._on_y else (g, 0.0)

    def __repr__(self) -> str:
        return f"Ramp(start={self.start!r}, end={self.end!r}, height={self.height!r}, axis={self.axis!r})"


class Sine:
    """Waviness ``amplitude * sin(2*pi*u/wavelength + phase)`` along ``axis`` (mm, mm, rad)."""

    def __init__(self, amplitude: float, wavelength: float, axis: str = "X", phase: float = 0.0):
        self.axis = _axis(axis, "Sine.axis")
        self.amplitude = require_number(amplitude, "Sine.amplitude", lo=0.0)
        # at least 1 nm: a shorter wavelength is no surface a sensor can follow, and 2*pi/lambda must stay finite
        self.wavelength = require_number(wavelength, "Sine.wavelength", lo=1e-6)
        self.phase = require_number(phase, "Sine.phase")
        self._on_y = self.axis == "Y"
        self._k = _TWO_PI / self.wavelength  # wave number (rad/mm)

    def z(self, x: float, y: float) -> float:
        return self.amplitude * math.sin(self._k * (y if self._on_y else x) + self.phase)

    def z_array(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        xs, ys = np.broadcast_arrays(np.asarray(xs, float), np.asarray(ys, float))
        return self.amplitude * np.sin(self._k * (ys if self._on_y else xs) + self.phase)

    def gradient(self, x: float, y: float) -> tuple[float, float]:
        g = self.amplitude * self._k * math.cos(self._k * (y if self._on_y else x) + self.phase)
        return (0.0, g) if self._on_y else (g, 0.0)

    def __repr__(self) -> str:
        return (f"Sine(amplitude={self.amplitude!r}, wavelength={self.wavelength!r}, axis={self.axis!r}, "
                f"phase={self.phase!r})")


class TiltedPlane:
    """Plane ``sx*(x - x0) + sy*(y - y0)`` with slopes in mm/mm (0 at the point ``(x0, y0)``).

    :meth:`from_angle` builds it from an angle (degrees) about X or Y using the right-hand rule:
    a positive rotation about Y tilts +X downwards (``sx = -tan(angle)``), a positive rotation about
    X tilts +Y upwards (``sy = tan(angle)``).
    """

    def __init__(self, sx: float = 0.0, sy: float = 0.0, x0: float = 0.0, y0: float = 0.0):
        self.sx = require_number(sx, "TiltedPlane.sx")
        self.sy = require_number(sy, "TiltedPlane.sy")
        self.x0 = require_number(x0, "TiltedPlane.x0")
        self.y0 = require_number(y0, "TiltedPlane.y0")

    @classmethod
    def from_angle(cls, angle_deg: float, about: str = "Y", x0: float = 0.0, y0: float = 0.0) -> TiltedPlane:
        about = _axis(about, "TiltedPlane.about")
        angle = require_number(angle_deg, "TiltedPlane.angle_deg", lo=-90.0, hi=90.0,
                               lo_open=True, hi_open=True)
        slope = math.tan(math.radians(angle))
        if about == "Y":
            return cls(sx=-slope, sy=0.0, x0=x0, y0=y0)
        return cls(sx=0.0, sy=slope, x0=x0, y0=y0)

    def z(self, x: float, y: float) -> float:
        return self.sx * (x - self.x0) + self.sy * (y - self.y0)

    def z_array(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        xs, ys = np.broadcast_arrays(np.asarray(xs, float), np.asarray(ys, float))
        return self.sx * (xs - self.x0) + self.sy * (ys - self.y0)

    def gradient(self, x: float, y: float) -> tuple[float, float]:
        return (self.sx, self.sy)

    def __repr__(self) -> str:
        return f"TiltedPlane(sx={self.sx!r}, sy={self.sy!r}, x0={self.x0!r}, y0={self.y0!r})"


class Holes:
    """Round holes (or round pockets) of one ``diameter`` at ``centers`` ``[(x, y), ...]`` (mm): the
    height contribution is ``height`` (mm, negative: a hole through a sheet, e.g. -30 down to the
    support table) inside a hole (distance from its centre < diameter / 2), 0 outside. Holes must not
    overlap (they would not add up: a point in two holes counts once).

    A per-cycle look-up costs one dictionary access, not one test per hole: the centres are sorted
    into a grid of cells of one diameter, each cell listing the holes that reach into it.
    :meth:`near` says whether any hole lies within ``reach`` of a point (a sensor's footprint).
    """

    def __init__(self, centers: Sequence[Sequence[float]], diameter: float, height: float):
        if not isinstance(centers, (list, tuple)) or not centers:
            raise ConfigError("Holes.centers", centers, "a non-empty list of [x, y] pairs (mm)")
        pts = []
        for n, c in enumerate(centers):
            key = f"Holes.centers[{n}]"
            if not isinstance(c, (list, tuple)) or len(c) != 2:
                raise ConfigError(key, c, "a pair [x, y] (mm)")
            pts.append((require_number(c[0], key + "[0]"), require_number(c[1], key + "[1]")))
        self.centers: tuple[tuple[float, float], ...] = tuple(pts)
        self.diameter = require_number(diameter, "Holes.diameter", lo=0.0, lo_open=True)
        self.height = require_number(height, "Holes.height")
        self.radius = self.diameter / 2.0
        self._r2 = self.radius * self.radius
        self._cell = self.diameter
        grid: dict[tuple[int, int], list[tuple[float, float]]] = {}
        for cx, cy in self.centers:
            for i in range(math.floor((cx - self.radius) / self._cell), math.floor((cx + self.radius) / self._cell) + 1):
                for j in range(math.floor((cy - self.radius) / self._cell),
                               math.floor((cy + self.radius) / self._cell) + 1):
                    grid.setdefault((i, j), []).append((cx, cy))
        self._grid = {k: tuple(v) for k, v in grid.items()}

    def z(self, x: float, y: float) -> float:
        cand = self._grid.get((math.floor(x / self._cell), math.floor(y / self._cell)))
        if cand is not None:
            r2 = self._r2
            for cx, cy in cand:
                dx = x - cx
                dy = y - cy
                if dx * dx + dy * dy < r2:
                    return self.height
        return 0.0

    def z_array(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        xs, ys = np.broadcast_arrays(np.asarray(xs, float), np.asarray(ys, float))
        inside = np.zeros(xs.shape, bool)
        for cx, cy in self.centers:
            inside |= (xs - cx) ** 2 + (ys - cy) ** 2 < self._r2
        return np.where(inside, self.height, 0.0)

    def gradient(self, x: float, y: float) -> tuple[float, float]:
        return (0.0, 0.0)                 # vertical walls: no slope (as a Step's vertical edge)

    def near(self, x: float, y: float, reach: float) -> bool:
        """True when a hole comes within ``reach`` mm of ``(x, y)`` (its rim closer than ``reach``)."""
        c = self._cell
        lim = (self.radius + reach) ** 2
        for i in range(math.floor((x - reach) / c), math.floor((x + reach) / c) + 1):
            for j in range(math.floor((y - reach) / c), math.floor((y + reach) / c) + 1):
                for cx, cy in self._grid.get((i, j), ()):
                    dx = x - cx
                    dy = y - cy
                    if dx * dx + dy * dy < lim:
                        return True
        return False

    def __repr__(self) -> str:
        return f"Holes(<{len(self.centers)} centers>, diameter={self.diameter!r}, height={self.height!r})"


class HeightMap:
    """Height grid with bilinear interpolation; outside the grid the edge values continue (clamp).

    ``heights[j][i]`` is the height (mm) at ``(xs[i], ys[j])``; ``xs`` and ``ys`` are strictly
    increasing with at least 2 points each.

    CSV format (:meth:`from_csv`): the first row holds the x coordinates after one leading cell
    (its text is ignored, e.g. ``y\\x`` or empty); every further row starts with its y coordinate
    followed by one height per x. Blank lines and lines starting with ``#`` are skipped.
    Separator: comma (``;`` is also accepted). Example::

        y\\x, 0, 10, 20
        0,    0, 0.1, 0.2
        5,    0, 0.2, 0.4
    """

    def __init__(self, xs: Sequence[float], ys: Sequence[float],
                 heights: Sequence[Sequence[float]] | np.ndarray):
        xs_a = np.asarray(xs, dtype=float)
        ys_a = np.asarray(ys, dtype=float)
        z_a = np.asarray(heights, dtype=float)
        for name, c in (("xs", xs_a), ("ys", ys_a)):
            if c.ndim != 1 or c.size < 2 or not np.all(np.isfinite(c)) or not np.all(np.diff(c) > 0):
                raise ConfigError(f"HeightMap.{name}", c.tolist() if c.size <= 8 else f"<{c.size} values>",
                                  "at least 2 finite, strictly increasing coordinates (mm)")
        if z_a.shape != (ys_a.size, xs_a.size) or not np.all(np.isfinite(z_a)):
            raise ConfigError("HeightMap.heights", f"<array of shape {z_a.shape}>",
                              f"finite heights (mm) of shape (len(ys), len(xs)) = ({ys_a.size}, {xs_a.size})")
        self.xs, self.ys, self.heights = xs_a, ys_a, z_a
        # Python lists for the scalar path: indexing lists of floats is much cheaper than numpy scalars.
        self._xl = xs_a.tolist()
        self._yl = ys_a.tolist()
        self._zl = z_a.tolist()
        self._nx, self._ny = xs_a.size, ys_a.size

    @classmethod
    def from_csv(cls, path: str | os.PathLike, key: str = "HeightMap.file") -> HeightMap:
        """Load a grid in the format described in the class docstring; errors name file and line."""
        path = os.fspath(path)
        try:
            with open(path, newline="", encoding="utf-8") as fh:
                text = fh.read()
        except OSError as exc:
            raise ConfigError(key, path, "a readable CSV file (relative paths: to the config's directory)",
                              f"cannot read ({exc.strerror}):") from None
        rows: list[tuple[int, list[str]]] = []
        for lineno, line in enumerate(text.splitlines(), start=1):
            stripped = line.strip()
            if not stripped or stripped.startswith("#"):
                continue
            delimiter = ";" if ";" in stripped and "," not in stripped else ","
            cells = next(csv.reader([stripped], delimiter=delimiter))
            rows.append((lineno, [c.strip() for c in cells]))
        if len(rows) < 3:
            raise ConfigError(key, path, "a header row of x coordinates and at least 2 rows of heights",
                              "too few rows in")

        def number(cell: str, lineno: int, what: str) -> float:
            try:
                v = float(cell)
            except ValueError:
                v = float("nan")
            if not math.isfinite(v):
                raise ConfigError(f"{key} ({path}:{lineno})", cell, f"a finite number ({what})")
            return v

        head_line, head = rows[0]
        xs = [number(c, head_line, "x coordinate, mm") for c in head[1:]]
        ys: list[float] = []
        heights: list[list[float]] = []
        for lineno, cells in rows[1:]:
            if len(cells) != len(xs) + 1:
                raise ConfigError(f"{key} ({path}:{lineno})", len(cells) - 1,
                                  f"{len(xs)} heights (one per x coordinate of line {head_line})",
                                  "wrong number of heights:")
            ys.append(number(cells[0], lineno, "y coordinate, mm"))
            heights.append([number(c, lineno, "height, mm") for c in cells[1:]])
        try:
            return cls(xs, ys, heights)
        except ConfigError as exc:
            raise exc.rekeyed(f"{key} ({path})") from None

    def _cell(self, coords: list[float], n: int, u: float) -> tuple[int, float, bool]:
        """Cell index ``i`` with ``coords[i] <= u <= coords[i+1]``, the fraction in it, and whether
        ``u`` lies strictly inside the grid along this coordinate (clamped otherwise)."""
        i = bisect.bisect_right(coords, u) - 1
        if i < 0:
            return 0, 0.0, False
        if i >= n - 1:
            return n - 2, 1.0, u == coords[-1]
        c0 = coords[i]
        return i, (u - c0) / (coords[i + 1] - c0), True

    def z(self, x: float, y: float) -> float:
        i, tx, _ = self._cell(self._xl, self._nx, x)
        j, ty, _ = self._cell(self._yl, self._ny, y)
        r0 = self._zl[j]
        r1 = self._zl[j + 1]
        z0 = r0[i] + (r0[i + 1] - r0[i]) * tx
        z1 = r1[i] + (r1[i + 1] - r1[i]) * tx
        return z0 + (z1 - z0) * ty

    def z_array(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        xs, ys = np.broadcast_arrays(np.asarray(xs, float), np.asarray(ys, float))
        i = np.clip(np.searchsorted(self.xs, xs, side="right") - 1, 0, self._nx - 2)
        j = np.clip(np.searchsorted(self.ys, ys, side="right") - 1, 0, self._ny - 2)
        tx = np.clip((xs - self.xs[i]) / (self.xs[i + 1] - self.xs[i]), 0.0, 1.0)
        ty = np.clip((ys - self.ys[j]) / (self.ys[j + 1] - self.ys[j]), 0.0, 1.0)
        zz = self.heights
        z0 = zz[j, i] + (zz[j, i + 1] - zz[j, i]) * tx
        z1 = zz[j + 1, i] + (zz[j + 1, i + 1] - zz[j + 1, i]) * tx
        return z0 + (z1 - z0) * ty

    def gradient(self, x: float, y: float) -> tuple[float, float]:
        i, tx, inside_x = self._cell(self._xl, self._nx, x)
        j, ty, inside_y = self._cell(self._yl, self._ny, y)
        r0, r1 = self._zl[j], self._zl[j + 1]
        dx = self._xl[i + 1] - self._xl[i]
        dy = self._yl[j + 1] - self._yl[j]
        # Outside the grid the edge value continues, so the slope across the edge is 0.
        gx = ((r0[i + 1] - r0[i]) * (1.0 - ty) + (r1[i + 1] - r1[i]) * ty) / dx if inside_x else 0.0
        z0 = r0[i] + (r0[i + 1] - r0[i]) * tx
        z1 = r1[i] + (r1[i + 1] - r1[i]) * tx
        gy = (z1 - z0) / dy if inside_y else 0.0
        return (gx, gy)

    def __repr__(self) -> str:
        return (f"HeightMap(<{self._nx} x {self._ny} grid, x {self._xl[0]}..{self._xl[-1]}, "
                f"y {self._yl[0]}..{self._yl[-1]}>)")


class Surface:
    """Workpiece surface: ``base`` (mm) plus the sum of ``features``."""

    def __init__(self, base: float = 0.0, features: Iterable[Feature] = ()):
        self.base = require_number(base, "Surface.base")
        self.features: tuple[Feature, ...] = tuple(features)
        # Bound methods cached once: saves an attribute lookup per feature per cycle.
        self._z_fns = tuple(f.z for f in self.features)

    def height(self, x: float, y: float = 0.0) -> float:
        """Surface height (mm) at ``(x, y)``: the per-cycle scalar path."""
        z = self.base
        for f in self._z_fns:
            z += f(x, y)
        return z

    def height_array(self, xs: np.ndarray | Sequence[float],
                     ys: np.ndarray | Sequence[float] | float = 0.0) -> np.ndarray:
        """Vectorised :meth:`height`; ``xs`` and ``ys`` broadcast against each other."""
        xs_a, ys_a = np.broadcast_arrays(np.asarray(xs, float), np.asarray(ys, float))
        z = np.full(xs_a.shape, self.base)
        for f in self.features:
            z = z + f.z_array(xs_a, ys_a)
        return z

    def gradient(self, x: float, y: float = 0.0) -> tuple[float, float]:
        """Slope ``(dz/dx, dz/dy)`` in mm/mm (analytic; 0 on vertical step edges)."""
        gx = gy = 0.0
        for f in self.features:
            a, b = f.gradient(x, y)
            gx += a
            gy += b
        return (gx, gy)

    def normal(self, x: float, y: float = 0.0) -> tuple[float, float, float]:
        """Unit surface normal ``(nx, ny, nz)`` pointing up (+Z, away from the workpiece)."""
        gx, gy = self.gradient(x, y)
        inv = 1.0 / math.sqrt(1.0 + gx * gx + gy * gy)
        return (-gx * inv, -gy * inv, inv)

    def __repr__(self) -> str:
        return f"Surface(base={self.base!r}, features={list(self.features)!r})"


# --- configuration ---------------------------------------------------------------------------------

#: feature type name -> (class, allowed keys besides "type", required keys)
FEATURE_TYPES: dict[str, tuple[type, tuple[str, ...], tuple[str, ...]]] = {
    "flat": (Flat, (), ()),
    "step": (Step, ("axis", "at", "height", "width", "ramp_length"), ("at", "height")),
    "ramp": (Ramp, ("axis", "start", "end", "height"), ("start", "end", "height")),
    "sine": (Sine, ("axis", "amplitude", "wavelength", "phase"), ("amplitude", "wavelength")),
    "tilted_plane": (TiltedPlane, ("sx", "sy", "angle_deg", "about", "x0", "y0"), ()),
    "heightmap": (HeightMap, ("file",), ("file",)),
    "holes": (Holes, ("centers", "diameter", "height"), ("centers", "diameter", "height")),
}


def _rekey(exc: ConfigError, class_name: str, path: str) -> ConfigError:
    """Turn a constructor's ``Step.width`` key into the config path ``surface.features[0].width``."""
    key = exc.key
    if key.startswith(class_name + "."):
        key = path + key[len(class_name):]
    return exc.rekeyed(key)


def _feature_from_config(cfg: object, path: str, base_dir: str) -> Feature:
    if not isinstance(cfg, dict):
        raise ConfigError(path, cfg, "a table/dict with a 'type' key", "not a table:")
    if "type" not in cfg:
        raise ConfigError(f"{path}.type", MISSING, "one of " + ", ".join(repr(t) for t in FEATURE_TYPES))
    kind = require_choice(cfg["type"], f"{path}.type", tuple(FEATURE_TYPES))
    cls, keys, required = FEATURE_TYPES[kind]
    require_mapping(cfg, path, ("type",) + keys, required)
    args = {k: v for k, v in cfg.items() if k != "type"}
    try:
        if cls is HeightMap:
            file = args["file"]
            if not isinstance(file, str) or not file:
                raise ConfigError(f"{path}.file", file, "a CSV file path (string)")
            full = file if os.path.isabs(file) else os.path.join(base_dir, file)
            return HeightMap.from_csv(full, key=f"{path}.file")
        if cls is TiltedPlane and ("angle_deg" in args or "about" in args):
            if "sx" in args or "sy" in args:
                bad = "sx" if "sx" in args else "sy"
                raise ConfigError(f"{path}.{bad}", args[bad],
                                  "either slopes sx/sy or angle_deg with about, not both")
            if "angle_deg" not in args:
                raise ConfigError(f"{path}.angle_deg", MISSING,
                                  "angle_deg (degrees, in (-90, 90)) together with about")
            return TiltedPlane.from_angle(args["angle_deg"], args.get("about", "Y"),
                                          args.get("x0", 0.0), args.get("y0", 0.0))
        return cls(**args)
    except ConfigError as exc:
        raise _rekey(exc, cls.__name__, path) from None


def surface_from_config(config: dict, base_dir: str | os.PathLike = ".", key: str = "surface") -> Surface:
    """Build a :class:`Surface` from a plain dict, validating every key.

    Example::

        {"base": 20.0, "features": [
            {"type": "step", "axis": "X", "at": 50.0, "height": 2.8, "width": 10.0},
            {"type": "sine", "axis": "X", "amplitude": 0.5, "wavelength": 40.0},
            {"type": "heightmap", "file": "map.csv"}]}

    Relative height-map paths are resolved against ``base_dir``. Any unknown key or type, or a bad
    value, raises :class:`ConfigError` naming the key path (``surface.features[1].wavelength``),
    the value and what is allowed.
    """
    require_mapping(config, key, ("base", "features"))
    base = require_number(config.get("base", 0.0), f"{key}.base")
    features_cfg = config.get("features", [])
    if not isinstance(features_cfg, list):
        raise ConfigError(f"{key}.features", features_cfg, "a list of feature tables", "not a list:")
    base_dir = os.fspath(base_dir)
    features = [_feature_from_config(f, f"{key}.features[{n}]", base_dir) for n, f in enumerate(features_cfg)]
    return Surface(base, features)
