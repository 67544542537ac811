"""Cutting-process functions on top of distance control (issue 16), as PLC programs (docs/process.md).

Each function is a PLC program that uses only what a TwinCAT PLC has: the HLI DistanceControl control
unit (``command_w``, ``enable_w``, ``command_semaphore_rw``, ``state_r``), the CNC objects, V.E.
variables and the channel's path status (``StateBahn_Data.D_ActiveFeed`` / ``D_CommandFeed``,
:class:`ChannelPathStatus`). A scenario configures them with ``[[process]]`` tables; the machine runs
them as one :class:`ProcessProgram` after the sensor's PLC program and before a run's own.
"""
from .auto_set_value import AUTO_DEFAULTS, AutoSetValue
from .base import ProcessFunction
from .calibrate import CALIBRATE_DEFAULTS, Calibrate, CalibrationRecord
from .channel import ChannelPathStatus
from .collision_retract import COLLISION_DEFAULTS, RETRACT_MARGIN, CollisionRetract
from .config import (
                     PROCESS_CLASSES,
                     PROCESS_COMMON_KEYS,
                     PROCESS_FUNCTIONS,
                     PROCESS_KEYS,
                     ProcessConfig,
                     make_process_program,
                     process_configs,
)
from .corner_lock import CORNER_DEFAULTS, CornerLock
from .hold import FreezeHold
from .lift import LIFT_DEFAULTS, Lift
from .program import ProcessProgram
from .touch_off import TOUCH_DEFAULTS, TouchOff
from .void_lock import VOID_DEFAULTS, VOID_THRESHOLD_MM_S, VOID_THRESHOLD_V_S, VoidLock

__all__ = ["ProcessFunction", "PROCESS_COMMON_KEYS", "CALIBRATE_DEFAULTS", "Calibrate", "CalibrationRecord",
           "AUTO_DEFAULTS", "AutoSetValue", "ChannelPathStatus", "PROCESS_CLASSES", "PROCESS_FUNCTIONS", "PROCESS_KEYS",
           "ProcessConfig", "make_process_program", "process_configs",
           "CORNER_DEFAULTS", "CornerLock", "FreezeHold", "ProcessProgram", "VOID_DEFAULTS",
           "VOID_THRESHOLD_MM_S", "VOID_THRESHOLD_V_S", "VoidLock",
           "TOUCH_DEFAULTS", "TouchOff", "COLLISION_DEFAULTS", "RETRACT_MARGIN", "CollisionRetract",
           "LIFT_DEFAULTS", "Lift"]
