"""The cycle core: the axis distance controller and the control law it runs.

Names are imported lazily so that ``distctrl.params`` can use the enumerations of this package
without importing the controller (which itself depends on ``distctrl.params``).
"""
from importlib import import_module

_EXPORTS = {
    "Action": "commands", "Command": "commands", "ObjectWrite": "commands", "WRITABLE_OBJECTS": "commands",
    "AxisDistanceController": "controller", "ControllerState": "controller", "Tuning": "controller",
    "CycleInput": "cycle_io", "CycleOutput": "cycle_io", "Result": "cycle_io",
    "FilterConfig": "filters", "SensorFilter": "filters",
    "FilterType": "kinds", "SensorSource": "kinds",
    "CommandSource": "states", "HliState": "states", "HliTransition": "states", "InternalState": "states",
    "Mode": "states",
}
__all__ = list(_EXPORTS)


def __getattr__(name):
    if name in _EXPORTS:
        return getattr(import_module(f"{__name__}.{_EXPORTS[name]}"), name)
    raise AttributeError(name)
