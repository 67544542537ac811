"""The live commissioning page of ``distctrl serve --ui`` / ``distctrl ui`` (docs/ui.md): a Bokeh server
in the serve process with a scope, an object browser, a PLC panel and a machine view over the served
machine. :class:`UiServer` serves it; :class:`MachineHub` is what every page shares."""
from .app import UiServer
from .hub import MachineHub

__all__ = ["UiServer", "MachineHub"]
