"""distctrl: CNC distance (height) control, the ISG-kernel control law as a pure cycle core."""
__version__ = "0.1.0"
