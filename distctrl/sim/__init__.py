"""The virtual machine around the cycle core: plant models, scenarios, the machine and ``run``."""
from importlib import import_module

__all__ = ["run", "RunResult", "Machine", "load_scenario", "scenario_from_dict", "scenario_from_text"]
_EXPORTS = {"run": "runner", "RunResult": "runner", "Machine": "machine", "load_scenario": "scenario",
            "scenario_from_dict": "scenario", "scenario_from_text": "scenario"}


def __getattr__(name):
    if name in _EXPORTS:
        return getattr(import_module(f"{__name__}.{_EXPORTS[name]}"), name)
    raise AttributeError(name)
