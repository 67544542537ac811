"""Per-cycle input and output of the axis distance controller (ruckig style: the caller owns both).

All quantities are float64 in mm and s (SPEC §1). The controller reads a :class:`CycleInput` and
fills a :class:`CycleOutput` the caller passes in, so a loop allocates nothing per cycle.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum

from ..errors import ErrorEvent


class Result(IntEnum):
    """What ``update()`` returns: like ruckig's result codes, errors are values."""

    OK = 0
    WARNING = 1      # a warning event was produced this cycle (e.g. 70332)
    ERROR = -1       # an error event was produced this cycle; the controller is in ERROR


@dataclass(slots=True)
class CycleInput:
    """What the GEO cycle hands the controller.

    ``commands`` are consumed (and the list is cleared) at the start of the cycle, in order.
    """

    programmed_position: float = 0.0   # p: interpolated command position of the axis, mm
    actual_position: float = 0.0       # a: actual position (motor encoder), mm
    sensor_increments: float = 0.0     # raw encoder-2 reading, increments (SECOND_ENCODER)
    sensor_variable: float = 0.0       # distance from a V.E. variable, mm (VARIABLE)
    override: float = 1.0              # axis feed override as a fraction, 0..1
    feed_hold: bool = False
    cyclic_set_pos: float | None = None   # PLC CyclicCommand.D_Position, mm (PLC-commanded only)
    cyclic_set_dist: float | None = None  # PLC CyclicCommand.D_Distance, mm (PLC-commanded only)
    set_distance_scale: float = 1.0    # CONST_DIST: the set distance in use is SET_DIST x this (3D: cos θ,
                                       # times the kinematic-98 extension: SPEC §11); 1 for the axis variant
    nc_line: int | None = None         # NC line being executed, for error reports
    commands: list = field(default_factory=list)


@dataclass(slots=True)
class CycleOutput:
    """Everything one cycle produces: the drive offset and the values behind every CNC object.

    Names follow the CNC objects of FCT-M3 §7.5/§9.4; units are mm, mm/s, mm/s², s.
    """

    # to the drive
    offset: float = 0.0                  # o = DIST_CTRL_IFC::actual_offset (mm here, Incr. as object)
    command_position: float = 0.0        # c = p + o (+ absorbed_offset in the cycle it happens)
    absorbed_offset: float = 0.0         # OFF NO_MOVE / reset: offset the channel takes over (mm)
    # CNC objects (internal units)
    set_pos: float = 0.0                 # DIST_CTRL::set_pos
    set_distance: float = 0.0            # DIST_CTRL::set_distance
    target_deviation: float = 0.0        # DIST_CTRL::target_deviation
    delta_deviation_pre_limiter: float = 0.0   # DIST_CTRL::delta_deviation_pre_limiter (u)
    m_actual_offset: float = 0.0         # DIST_CTRL::m_actual_offset
    sloped_delta_deviation: float = 0.0  # DIST_CTRL_IFC::sloped_delta_deviation (v*T)
    delta_offset: float = 0.0            # DIST_CTRL_IFC::delta_offset (o_k - o_k-1)
    sensor_value: float = 0.0            # DIST_CTRL::sensor_value (encoder reading s, or the variable)
    feedback_value: float = 0.0          # DIST_CTRL::feedback_value (surface or distance)
    filtered_feedback: float = 0.0       # DIST_CTRL::filtered_feedback
    state: int = 0                       # DIST_CTRL::state (internal code, see InternalState)
    hli_state: int = 0                   # state_r.actual_state (HliState)
    kp: float = 1.0                      # DIST_CTRL::kp (working value)
    i_tn: float = 0.0                    # DIST_CTRL::i_tn
    d_tv: float = 0.0                    # DIST_CTRL::d_tv
    smoothing_fact: float = 0.7          # DIST_CTRL::smoothing_fact
    kalman_sigma: float = 4.0            # DIST_CTRL::kalman_sigma
    n_cycles: int = 4                    # DIST_CTRL::n_cycles
    filter_type: str = "DEFAULT"         # DIST_CTRL::filter_type
    v_max_int: float = 0.0               # DIST_CTRL::v_max_int: velocity limit applied (mm/s)
    a_max_int: float = 0.0               # DIST_CTRL_IFC::a_max_int: acceleration limit applied (mm/s²)
    v_max_param: float = 0.0             # DIST_CTRL_PARAM[0]::v_max, working value (mm/s)
    a_max_param: float = 0.0             # DIST_CTRL_PARAM[0]::a_max, working value (mm/s², 0 = axis)
    # PLC state_r
    surface_position: float = 0.0        # state_r.actual_position: a - d (mm)
    measured_distance: float = 0.0       # state_r actual distance d (mm)
    command_source: int = 0              # state_r command source, 0 NC / 1 PLC
    # bookkeeping
    offset_velocity: float = 0.0         # v: offset velocity applied this cycle (mm/s)
    target_reached: bool = True          # |e| <= max(tolerance, 1 µm) in a running state; INACTIVE
    sensor_valid: bool = True            # False when this cycle's sensor input was not finite
    cycle: int = 0
    vals: tuple = (0.0, 0.0, 0.0, 0.0, 0.0)
    tuning_stamp: object = None          # which tuning the tuning fields above show (internal)
    events: list[ErrorEvent] = field(default_factory=list)   # errors and warnings of this cycle
