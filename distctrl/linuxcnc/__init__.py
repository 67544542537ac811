"""distctrl meets LinuxCNC (issue 29): LinuxCNC's ``plasmac`` component in closed loop on distctrl's
virtual plate, run in ``halrun`` (Debian's ``linuxcnc-uspace``), side by side with distctrl's own
controller and process functions (docs/linuxcnc.md).

* :mod:`distctrl.linuxcnc.hal_env` - the HAL session: the environment halrun needs as root, building
  and installing the components of ``hal/`` with ``halcompile``, halcmd, Python's ``hal`` module;
* :mod:`distctrl.linuxcnc.bench` - ``distctrl linuxcnc bench``: the plant (path, Z drive with external
  offsets, arc voltage, float switch) around plasmac, lock-step with the servo thread, and the report.
"""
