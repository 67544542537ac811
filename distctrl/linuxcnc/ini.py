"""A LinuxCNC INI file as LinuxCNC reads it (docs/linuxcnc.md "thc-setp"): ``[SECTION]``, ``KEY = VALUE``,
comments (``#``, ``;``) on their own lines, ``#INCLUDE file`` (relative to the including file, as the
``linuxcnc`` script expands it), and the first of repeated keys for a single value (LinuxCNC's
``iniFind``; ``HALFILE`` and the like are repeated on purpose: :meth:`Ini.all`).

:func:`external_offset_limits` gives the Z axis's limits for external offsets, the only way a THC
component moves Z: MAX_VELOCITY and MAX_ACCELERATION × OFFSET_AV_RATIO (motion(9): without
OFFSET_AV_RATIO, LinuxCNC applies no external offset to the axis).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from .hal_env import LinuxCNCError

__all__ = ["Ini", "read_ini", "OffsetLimits", "external_offset_limits"]


@dataclass(frozen=True)
class Entry:
    key: str
    value: str
    file: Path
    line: int


class Ini:
    """The entries per section, in file order (includes expanded in place)."""

    def __init__(self, path: Path, sections: dict[str, list[Entry]]):
        self.path = path
        self.sections = sections

    def entry(self, section: str, key: str) -> Entry | None:
        for e in self.sections.get(section, []):
            if e.key == key:
                return e
        return None

    def get(self, section: str, key: str, default: str | None = None) -> str | None:
        e = self.entry(section, key)
        return default if e is None else e.value

    def all(self, section: str, key: str) -> list[str]:
        return [e.value for e in self.sections.get(section, []) if e.key == key]

    def number(self, section: str, key: str, lo: float, hi: float, lo_open: bool = False) -> float:
        """A number within lo..hi; :class:`LinuxCNCError` naming file, line, key and range otherwise."""
        e = self.entry(section, key)
        if e is None:
            raise LinuxCNCError(f"{self.path}: [{section}]{key} is missing")
        try:
            v = float(e.value)
        except ValueError:
            v = math.nan
        if not (math.isfinite(v) and (lo < v if lo_open else lo <= v) and v <= hi):
            raise LinuxCNCError(f"{e.file}:{e.line}: [{section}]{key} = {e.value!r}; allowed: "
                                f"{lo:g} {'<' if lo_open else '<='} value <= {hi:g}")
        return v


def read_ini(path: str | Path) -> Ini:
    """Read a LinuxCNC INI file; :class:`LinuxCNCError` (one line) if it or an include cannot be read."""
    path = Path(path)
    sections: dict[str, list[Entry]] = {}
    _read(path, sections, None, 0)
    return Ini(path, sections)


def _read(path: Path, sections: dict, section: str | None, depth: int) -> str | None:
    if depth > 8:
        raise LinuxCNCError(f"{path}: #INCLUDE nested more than 8 deep")
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise LinuxCNCError(f"INI file {path} cannot be read ({exc.strerror})") from None
    for n, raw in enumerate(text.lstrip("\ufeff").splitlines(), 1):
        line = raw.strip()
        if line.startswith("#INCLUDE"):
            inc = line[len("#INCLUDE"):].strip()
            section = _read((path.parent / inc).resolve() if not Path(inc).is_absolute() else Path(inc),
                            sections, section, depth + 1)
            continue
        if not line or line[0] in "#;":
            continue
        if line.startswith("[") and "]" in line:
            section = line[1:line.index("]")].strip()
            sections.setdefault(section, [])
            continue
        key, sep, value = line.partition("=")
        if sep and section is not None:
            sections[section].append(Entry(key.strip(), value.strip(), path, n))
    return section


@dataclass(frozen=True)
class OffsetLimits:
    """The Z axis's external-offset limits (mm/s, mm/s²) and where they come from."""
    v_max: float
    a_max: float
    axis_v_max: float
    axis_a_max: float
    ratio: float
    source: str

    def describe(self) -> str:
        return (f"{self.source}: [AXIS_Z] MAX_VELOCITY {self.axis_v_max:g} x OFFSET_AV_RATIO {self.ratio:g}"
                f" = {self.v_max:g} mm/s, MAX_ACCELERATION {self.axis_a_max:g} x {self.ratio:g}"
                f" = {self.a_max:g} mm/s²")


def external_offset_limits(ini: Ini) -> OffsetLimits:
    """[AXIS_Z]'s external-offset limits (motion(9): MAX_VELOCITY and MAX_ACCELERATION × OFFSET_AV_RATIO)."""
    if ini.entry("AXIS_Z", "OFFSET_AV_RATIO") is None:
        raise LinuxCNCError(f"{ini.path}: [AXIS_Z]OFFSET_AV_RATIO is missing: LinuxCNC applies no external "
                            "offset to Z without it (motion(9)), so no THC component can move Z")
    v = ini.number("AXIS_Z", "MAX_VELOCITY", 0.0, 1e6, lo_open=True)
    a = ini.number("AXIS_Z", "MAX_ACCELERATION", 0.0, 1e8, lo_open=True)
    r = ini.number("AXIS_Z", "OFFSET_AV_RATIO", 0.0, 0.9, lo_open=True)
    return OffsetLimits(v * r, a * r, v, a, r, str(ini.path))
