"""Commands of the 3D (channel-specific) distance control (FCT-M3 ch. 12, PROG #DIST CTRL).

An NC block ``#DIST CTRL ON [CONST_DIST SET_DIST=1 MODE=ACS DIRECTION=Z]`` becomes one
:class:`Command3D` (``DistCtrl3DWord.to_command3d(lookup, line)`` in :mod:`distctrl.nc.program`).
It carries what the axis :class:`~distctrl.control.commands.Command` carries plus the 3D options
(WAIT, MODE, DIRECTION, FILTER_TIME); :meth:`Command3D.core_command` gives the part the shared
cycle core understands. All lengths are mm, times s (SPEC §1).
"""
from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

from ..base.kinds import FilterType, SensorSource
from ..base.states import CommandSource
from .commands import Action, Command


class CompensationMode(IntEnum):
    """``MODE=<ident>``: where the distance-control offset is superimposed (FCT-M3 §12.2, SPEC §11)."""

    OFF = 0   # computed, not superimposed (the default)
    PCS = 1   # programmed coordinates (an active #CS rotates the direction)
    MCS = 2   # machine coordinate system (Cartesian basic system), orthogonal to the surface
    ECS = 3   # tool direction; needs kinematic 98 active (#KIN ID[98], #TRAFO ON)
    ACS = 4   # physical axis level (with DIRECTION=Z: as the axis variant on Z)

    @classmethod
    def parse(cls, name: str) -> "CompensationMode":
        key = name.strip().upper()
        if key not in cls.__members__:
            raise ValueError(f"unknown MODE {name!r}; allowed: {', '.join(cls.__members__)}")
        return cls[key]


#: DIRECTION=<axis_name>: the documents support Z and have X/Y "in preparation"
DIRECTION_NAMES = ("X", "Y", "Z")
#: SENSOR_SOURCE values of the 3D variant; DEFAULT means VARIABLE (FCT-M3 §12.2)
SENSOR_SOURCES_3D = ("DEFAULT", "VARIABLE")


@dataclass(frozen=True, slots=True)
class Command3D:
    """One ``#DIST CTRL`` command. Optional fields left at ``None`` are not changed.

    ``const_dist`` selects CONST_DIST for ON/DRYRUN; otherwise a select is SURFACE (SET_POS)
    mode, written or not (:attr:`surface`). ``sensor_source`` is already resolved: SENSOR_SOURCE=DEFAULT
    arrives as ``SensorSource.VARIABLE``. ``filter_time`` is in interpolator cycles (sin² blend
    of activation and deactivation, SPEC §11; 0 = none).
    """

    action: Action = Action.NONE
    wait: bool = False
    const_dist: bool = False
    no_move: bool = False
    set_pos: float | None = None        # mm, absolute position of the workpiece surface
    set_dist: float | None = None       # mm, distance to the workpiece surface
    ref_position: float | None = None   # mm, REF: position of the workpiece surface now (None: sensor zero)
    mode: CompensationMode | None = None
    direction: str | None = None        # "X", "Y" or "Z"
    kp: float | None = None
    i_tn: float | None = None           # s
    d_tv: float | None = None           # s
    filter_type: FilterType | None = None
    filter_time: int | None = None      # interpolator cycles
    n_cycles: int | None = None
    fg_f0: float | None = None          # Hz
    order: int | None = None
    smooth_fact: float | None = None
    kalman_sigma: float | None = None
    sensor_source: SensorSource | None = None
    sensor_var: str | None = None       # "V.E.NAME"
    vals: tuple[float | None, ...] = (None, None, None, None, None)   # VAL1..VAL5
    source: CommandSource = CommandSource.NC
    line: int | None = None

    @property
    def surface(self) -> bool:
        """A select (ON/DRYRUN) in SURFACE mode (SET_POS), written as SURFACE or implied."""
        return self.action in (Action.ON, Action.DRYRUN) and not self.const_dist

    @property
    def is_select(self) -> bool:
        return self.action in (Action.ON, Action.DRYRUN)

    def core_command(self) -> Command:
        """The part of this command the shared cycle core understands (an axis :class:`Command`).

        WAIT, MODE, DIRECTION and FILTER_TIME are the 3D runtime's business and are dropped.
        """
        return Command(action=self.action, const_dist=self.const_dist, no_move=self.no_move,
                       set_pos=self.set_pos, set_dist=self.set_dist, ref_position=self.ref_position,
                       kp=self.kp, i_tn=self.i_tn, d_tv=self.d_tv, filter_type=self.filter_type,
                       n_cycles=self.n_cycles, fg_f0=self.fg_f0, order=self.order,
                       smooth_fact=self.smooth_fact, kalman_sigma=self.kalman_sigma,
                       sensor_source=self.sensor_source, sensor_var=self.sensor_var, vals=self.vals,
                       source=self.source, line=self.line)


__all__ = ["Command3D", "CompensationMode", "DIRECTION_NAMES", "SENSOR_SOURCES_3D"]
