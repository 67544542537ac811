"""The cycle core: the axis distance controller and the control law it runs.

It stands on :mod:`distctrl.params`, :mod:`distctrl.errors` and the vocabulary of :mod:`distctrl.base`
(docs/architecture.md). The enumerations ``FilterType``, ``SensorSource``, ``HliState``, ... live in
:mod:`distctrl.base` and are re-exported here. The other names are resolved on first use, so that
importing one module of this package (``distctrl.control.law`` for the numba batch kernel) does not
load the controller.
"""
from importlib import import_module

from ..base.kinds import FilterType, SensorSource
from ..base.states import CommandSource, HliState, HliTransition, InternalState, Mode

_EXPORTS = {
    "Action": "commands", "Command": "commands", "ObjectWrite": "commands", "WRITABLE_OBJECTS": "commands",
    "AxisDistanceController": "controller", "ControllerState": "controller", "Tuning": "controller",
    "CycleInput": "cycle_io", "CycleOutput": "cycle_io", "Result": "cycle_io",
    "FilterConfig": "filters", "SensorFilter": "filters",
}
__all__ = [*_EXPORTS, "FilterType", "SensorSource", "CommandSource", "HliState", "HliTransition", "InternalState",
           "Mode"]


def __getattr__(name):
    if name in _EXPORTS:
        return getattr(import_module(f"{__name__}.{_EXPORTS[name]}"), name)
    raise AttributeError(name)
