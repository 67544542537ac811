"""``distctrl linuxcnc config``: a complete LinuxCNC QtPlasmaC configuration with distctrl_thc
(docs/linuxcnc.md "A QtPlasmaC configuration with distctrl_thc", issue 40).

It reads a QtPlasmaC configuration - by default Debian's installed sim
(/usr/share/doc/linuxcnc/examples/sample-configs/sim/qtplasmac), or the user's own with ``--from`` -
and writes a new one into OUTDIR: a copy of the source's files (the source is not changed; nothing of
LinuxCNC is kept in this repository) with

* ``distctrl_thc.hal`` (a HALFILE right after qtplasmac_comp.hal): distctrl_thc's parameters (the
  named, commented ``thc-setp`` lines, v-max/a-max capped to the INI's external-offset limits) and its
  wiring: the arc voltage on QtPlasmaC's own signal ``plasmac:arc_voltage_out`` (the GUI's display and
  its later ``net`` only add their pins), the corner and void lock on QtPlasmaC's anti-dive switches
  (``plasmac:cornerlock-enable``, ``plasmac:voidlock-enable``), the cut height from the material
  (``plasmac:cut-height``), the THC delay (``plasmac:thc-delay``), and the enable, the Z offset sum and
  the LEDs through distctrl_qtplasmac (hal/distctrl_qtplasmac.comp: on only while plasmac cuts with the
  torch on and the arc OK, so M5 ends the control before the voltage drops). It loads only distctrl's
  own modules, each once: it does not depend on TWOPASS.
* ``distctrl_postgui.hal`` (the last POSTGUI_HALFILE): plasmac's own THC held off (QtPlasmaC's THC
  switch now switches distctrl_thc), QtPlasmaC's THC LEDs (enabled, active, up, down) from
  distctrl_thc; in the sim, the height-dependent torch (hal/distctrl_simtorch.comp) in place of
  Debian's sim-torch for the arc voltage and the float switch.
* the [HAL] section of the file that has it (the INI or its #INCLUDE) with these two lines added, the
  relative ``../../nc_files`` paths (the sample configs') made absolute, and in the sim the prefs' THC,
  corner lock and void lock switches on and a default material.
"""
from __future__ import annotations

import dataclasses
import re
import shutil
from dataclasses import dataclass
from pathlib import Path

from ..params import load_list
from .hal_env import LinuxCNCError
from .ini import Ini, external_offset_limits, read_ini
from .thc import ThcConfig

__all__ = ["DEBIAN_SIM", "SimTorch", "write_config", "ConfigResult"]

DEBIAN_SIM = Path("/usr/share/doc/linuxcnc/examples/sample-configs/sim/qtplasmac")
DEBIAN_SIM_INI = "qtplasmac_l_metric.ini"
#: the Z list the configuration starts from (a plasma torch's Z: KP 0.1, a 20-period moving average, both
#: encoders; v_max/a_max are then capped to the INI's external-offset limits)
TEMPLATE_LIST = Path(__file__).resolve().parent / "hal" / "z_qtplasmac.lis"
HAL_FILE = "distctrl_thc.hal"
POSTGUI_FILE = "distctrl_postgui.hal"


@dataclass(frozen=True)
class SimTorch:
    """The sim torch's plate (hal/distctrl_simtorch.comp's pins): a plate rising ``slope`` mm/mm from
    ``surface_z`` at X 0 with a warp, a hole along X, noise; the arc's linearisation v0 + k·h."""
    surface_z: float = -132.0
    slope: float = 0.005
    warp: float = 0.5
    warp_period: float = 300.0
    hole_x0: float = 200.0
    hole_width: float = 8.0
    hole_volts: float = 30.0
    v0: float = 95.0
    k: float = 6.0
    noise: float = 0.5
    float_travel: float = 1.5

    def setp_lines(self, name: str = "distctrl-simtorch.0") -> list[str]:
        return [f"setp {name}.{f.name.replace('_', '-')} {getattr(self, f.name)!r}"
                for f in dataclasses.fields(self)]


@dataclass
class ConfigResult:
    out: Path
    ini: Path
    source: Path
    sim: bool
    notes: list[str]
    hal_section_file: Path


def _pick_ini(source: Path, ini_name: str | None, sim: bool) -> Path:
    if ini_name is not None:
        ini = source / ini_name
        if not ini.is_file():
            raise LinuxCNCError(f"--ini {ini_name}: no such INI file in {source}")
        return ini
    if sim:
        return source / DEBIAN_SIM_INI
    cands = [p for p in sorted(source.glob("*.ini"))
             if "qtplasmac" in (read_ini(p).get("DISPLAY", "DISPLAY") or "")]
    if len(cands) != 1:
        names = ", ".join(p.name for p in cands) or "none"
        raise LinuxCNCError(f"{source}: {len(cands)} QtPlasmaC INI files ({names}); name one with --ini")
    return cands[0]


def _hal_section_file(ini: Ini) -> Path:
    """The file whose [HAL] section holds HALFILE = qtplasmac_comp.hal (the INI or an #INCLUDE)."""
    for e in ini.sections.get("HAL", []):
        if e.key == "HALFILE" and Path(e.value).name == "qtplasmac_comp.hal":
            return e.file
    raise LinuxCNCError(f"{ini.path}: [HAL] has no HALFILE = qtplasmac_comp.hal: "
                        "not a QtPlasmaC configuration")


def _add_hal_lines(path: Path) -> None:
    """HALFILE = distctrl_thc.hal after qtplasmac_comp.hal; POSTGUI_HALFILE = distctrl_postgui.hal last."""
    lines = path.read_text(encoding="utf-8").splitlines()
    out, in_hal, last_postgui, comp_at = [], False, None, None
    for ln in lines:
        s = ln.strip()
        if s.startswith("["):
            in_hal = s.startswith("[HAL]")
        out.append(ln)
        if in_hal and re.match(r"HALFILE\s*=\s*\S*qtplasmac_comp\.hal\s*$", s):
            comp_at = len(out)
            out += ["# distctrl_thc: its parameters and wiring (distctrl linuxcnc config)",
                    f"HALFILE                 = {HAL_FILE}"]
        if in_hal and s.startswith("POSTGUI_HALFILE"):   # after the sim's sim_postgui.hal (its sim-torch)
            last_postgui = len(out)
    if comp_at is None:
        raise LinuxCNCError(f"{path}: [HAL] has no HALFILE = qtplasmac_comp.hal")
    lines = ["# distctrl_thc's GUI side, last: plasmac's THC off, the LEDs, the sim torch",
             f"POSTGUI_HALFILE         = {POSTGUI_FILE}"]
    at = comp_at + 2 if last_postgui is None else last_postgui
    out[at:at] = lines
    path.write_text("\n".join(out) + "\n", encoding="utf-8")


def _absolute_paths(path: Path, source_dir: Path) -> None:
    """The sim's relative ../../nc_files (PROGRAM_PREFIX, SUBROUTINE_PATH, USER_M_PATH) made absolute."""
    text = path.read_text(encoding="utf-8")
    target = (source_dir / "../../nc_files").resolve()
    if target.is_dir():
        text = text.replace("../../nc_files", str(target))
    path.write_text(text, encoding="utf-8")


def _set_prefs(path: Path, section: str, values: dict[str, str]) -> None:
    """Set keys of one section of a QtPlasmaC prefs file (added if missing), other lines untouched."""
    lines = path.read_text(encoding="utf-8").splitlines() if path.exists() else []
    start = next((i for i, ln in enumerate(lines) if ln.strip() == f"[{section}]"), None)
    if start is None:
        lines += ["", f"[{section}]"] + [f"{k} = {v}" for k, v in values.items()]
    else:
        end = next((i for i in range(start + 1, len(lines)) if lines[i].startswith("[")), len(lines))
        todo = dict(values)
        for i in range(start + 1, end):
            key = lines[i].split("=", 1)[0].strip()
            if key in todo:
                lines[i] = f"{key} = {todo.pop(key)}"
        lines[end:end] = [f"{k} = {v}" for k, v in todo.items()]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def wiring_lines() -> list[str]:
    """distctrl_thc.hal's wiring (after its parameters): see the module docstring."""
    return [
        "",
        "# --- wiring (generated by `distctrl linuxcnc config`; do not edit by hand) ---",
        "# distctrl's glue and, in the sim, its torch: distctrl's own modules, each loaded once",
        "# (no module another HAL file loads: TWOPASS is not needed)",
        "loadrt distctrl_qtplasmac names=distctrl-qtplasmac.0",
        "addf distctrl-qtplasmac.0 servo-thread",
        "addf distctrl-thc.0 servo-thread",
        "# the arc voltage stays on QtPlasmaC's own signal: the GUI's `net plasmac:arc_voltage_out ...",
        "# qtplasmac.arc_voltage` then only adds the display's pin",
        "net plasmac:arc_voltage_out plasmac.arc-voltage-out => distctrl-thc.0.arc-voltage-in",
        "net plasmac:current-velocity => distctrl-thc.0.current-velocity",
        "net plasmac:feed-upm => distctrl-thc.0.feed-upm",
        "net plasmac:axis-position => distctrl-thc.0.axis-z-position",
        "# the locks follow QtPlasmaC's anti-dive switches (VELOCITY ANTI DIVE, VOID ANTI DIVE); the GUI",
        "# adds its switches to these signals when it starts",
        "net plasmac:cornerlock-enable => distctrl-thc.0.cornerlock-enable",
        "net plasmac:voidlock-enable => distctrl-thc.0.voidlock-enable",
        "net plasmac:cornerlock-threshold => distctrl-thc.0.cornerlock-threshold",
        "# the cut height from the material (entered once, in QtPlasmaC); the THC delay from its parameters",
        "# (no enable below min-cut-height: a material without a cut height never lowers the torch to 0)",
        "net plasmac:cut-height => distctrl-thc.0.set-dist distctrl-qtplasmac.0.cut-height",
        "net plasmac:thc-delay => distctrl-qtplasmac.0.thc-delay",
        "# on while QtPlasmaC's THC switch is on and plasmac cuts with the torch on and the arc OK (after",
        "# the THC delay); off in the period M5 or plasmac's state ends the cut: its offset runs out to 0",
        "net plasmac:thc-enable => distctrl-qtplasmac.0.thc-enable-in",
        "# (plasmac:state and plasmac:arc_ok_out are the signals QtPlasmaC's GUI nets these pins to)",
        "net plasmac:state plasmac.state-out => distctrl-qtplasmac.0.plasmac-state",
        "net plasmac:torch-on => distctrl-qtplasmac.0.torch-on",
        "net plasmac:arc_ok_out plasmac.arc-ok-out => distctrl-qtplasmac.0.arc-ok",
        "net plasmac:feed-hold => distctrl-qtplasmac.0.feed-hold",
        "net dthc:enable distctrl-qtplasmac.0.thc-enable-out => distctrl-thc.0.thc-enable",
        "# p for both encoders: Z as commanded plus plasmac's offset; a: the Z joint's feedback",
        "net dthc:z-pos-cmd axis.z.pos-cmd => distctrl-qtplasmac.0.z-pos-cmd",
        "net plasmac:offset-scale => distctrl-thc.0.resolution distctrl-qtplasmac.0.offset-scale",
        "net dthc:z-command distctrl-qtplasmac.0.z-command => distctrl-thc.0.axis-z-command",
        "# the Z offset: plasmac's counts plus distctrl_thc's",
        "unlinkp axis.z.eoffset-counts",
        "net plasmac:z-offset-counts => distctrl-qtplasmac.0.plasmac-counts",
        "net dthc:own-counts distctrl-thc.0.z-offset-counts => distctrl-qtplasmac.0.own-counts",
        "net dthc:z-offset-counts distctrl-qtplasmac.0.z-offset-counts-out => axis.z.eoffset-counts",
        "# QtPlasmaC's LEDs are driven from distctrl_thc (distctrl_postgui.hal connects them)",
        "net dthc:state distctrl-thc.0.state => distctrl-qtplasmac.0.dthc-state",
        "net dthc:velocity distctrl-thc.0.velocity => distctrl-qtplasmac.0.dthc-velocity",
    ]


def postgui_lines(sim: bool, distctrl: bool = True) -> list[str]:
    lines = [] if not distctrl else [
        "# distctrl_thc's GUI side: generated by `distctrl linuxcnc config`; do not edit by hand.",
        "# plasmac's own THC stays off: QtPlasmaC's THC switch (the plasmac:thc-enable signal) switches",
        "# distctrl_thc (distctrl_thc.hal); plasmac still probes, pierces, watches the arc and ends the cut",
        "unlinkp plasmac.thc-enable",
        "setp plasmac.thc-enable 0",
        "# QtPlasmaC's THC LEDs show distctrl_thc: enabled, active, up, down",
        "unlinkp qtplasmac.led_thc_enabled",
        "unlinkp qtplasmac.led_thc_active",
        "unlinkp qtplasmac.led_thc_up",
        "unlinkp qtplasmac.led_thc_down",
        "unlinkp qtplasmac.led_corner_lock",
        "unlinkp qtplasmac.led_void_lock",
        "net dthc:led-enabled distctrl-qtplasmac.0.led-enabled => qtplasmac.led_thc_enabled",
        "net dthc:led-active distctrl-qtplasmac.0.led-active => qtplasmac.led_thc_active",
        "net dthc:led-up distctrl-qtplasmac.0.led-up => qtplasmac.led_thc_up",
        "net dthc:led-down distctrl-qtplasmac.0.led-down => qtplasmac.led_thc_down",
        "net dthc:cornerlock-is-locked distctrl-thc.0.cornerlock-is-locked => qtplasmac.led_corner_lock",
        "net dthc:voidlock-is-locked distctrl-thc.0.voidlock-is-locked => qtplasmac.led_void_lock",
    ]
    if sim:
        lines += [
            "",
            "# the sim: distctrl's height-dependent torch in place of Debian's sim-torch (arc voltage)",
            "# and of the sim panel's float switch button",
            "unlinkp plasmac.arc-voltage-in",
            "net dthc:sim-voltage distctrl-simtorch.0.voltage => plasmac.arc-voltage-in",
            "unlinkp db_float.in",
            "net dthc:sim-float distctrl-simtorch.0.float-switch => db_float.in",
        ]
    return lines


def sim_lines(torch: SimTorch) -> list[str]:
    return ["",
            "# --- the sim torch (hal/distctrl_simtorch.comp): arc voltage from the torch's height ---",
            "loadrt distctrl_simtorch names=distctrl-simtorch.0",
            "addf distctrl-simtorch.0 servo-thread",
            *torch.setp_lines(),
            "net plasmac:torch-on => distctrl-simtorch.0.torch-on",
            "net plasmac:axis-x-position => distctrl-simtorch.0.x",
            "net plasmac:axis-position => distctrl-simtorch.0.z"]


def write_config(out: str | Path, source: str | Path | None = None, ini_name: str | None = None,
                 list_file: str | Path | None = None, sim_torch: SimTorch | None = None,
                 laser: bool = False, thc: str = "distctrl") -> ConfigResult:
    """Write the configuration (module docstring); :class:`LinuxCNCError` (one line) when it cannot.
    ``thc="plasmac"``: the sim with its height-dependent torch and plasmac's own THC, no distctrl_thc
    (the baseline to compare with)."""
    if thc not in ("distctrl", "plasmac"):
        raise LinuxCNCError(f"--thc {thc!r}: allowed distctrl, plasmac")
    if thc == "plasmac" and source is not None:
        raise LinuxCNCError("--thc plasmac writes the sim baseline (the sim torch with plasmac's THC): "
                            "without --from")
    if laser:
        raise LinuxCNCError("--laser is not built yet (issue 40: a capacitive sensor's input and its "
                            "calibration); the plasma configuration is")
    sim = source is None
    src = DEBIAN_SIM if sim else Path(source).resolve()
    if not src.is_dir():
        raise LinuxCNCError(f"{src}: no such configuration directory"
                            + (" (Debian's linuxcnc-uspace installs the QtPlasmaC sim there)" if sim else ""))
    out = Path(out).resolve()
    if out == src or src in out.parents:
        raise LinuxCNCError(f"{out}: OUTDIR must not be inside the source configuration {src} "
                            "(it is left as is)")
    if out.exists() and any(out.iterdir()):
        raise LinuxCNCError(f"{out} exists and is not empty: give a new directory")
    ini_src = _pick_ini(src, ini_name, sim)
    lim = external_offset_limits(read_ini(ini_src))
    lst = Path(list_file) if list_file is not None else TEMPLATE_LIST
    if not lst.is_file():
        raise LinuxCNCError(f"--list {lst}: no such axis parameter list")
    cfg = ThcConfig.from_params(load_list(lst).params)
    notes = []
    for key, have, cap in (("v-max", cfg.v_max, lim.v_max), ("a-max", cfg.a_max, lim.a_max)):
        if have > cap:
            notes.append(f"{key} {have:g} of {lst.name} capped to {cap:g} (the external-offset limit)")
    cfg = dataclasses.replace(cfg, v_max=min(cfg.v_max, lim.v_max), a_max=min(cfg.a_max, lim.a_max))

    shutil.copytree(src, out, dirs_exist_ok=True)
    ini_out = out / ini_src.name
    ini = read_ini(ini_out)
    hal_file = _hal_section_file(ini)
    _add_hal_lines(hal_file)
    for f in {ini_out, hal_file}:                   # OUTDIR is elsewhere: the relative nc_files path
        _absolute_paths(f, src)
    doc = cfg.setp_document(0.001, str(lst), notes=("v-max, a-max within " + lim.describe(),
                                                     *[f"warning: {n}" for n in notes]))
    if thc == "plasmac":
        lines = ["# the sim baseline: plasmac's own THC on distctrl's height-dependent sim torch,",
                 "# no distctrl_thc",
                 "# (generated by `distctrl linuxcnc config --thc plasmac`; do not edit by hand)"]
    else:
        lines = doc + wiring_lines()
    if sim:
        lines += sim_lines(sim_torch or SimTorch())
    (out / HAL_FILE).write_text("\n".join(lines) + "\n", encoding="utf-8")
    (out / POSTGUI_FILE).write_text("\n".join(postgui_lines(sim, distctrl=thc == "distctrl")) + "\n",
                                    encoding="utf-8")
    if sim:
        machine = ini.get("EMC", "MACHINE") or "qtplasmac"
        prefs = out / f"{machine}.prefs"
        _set_prefs(prefs, "ENABLE_OPTIONS", {"THC enable": "True", "Corner lock enable": "True",
                                              "Void lock enable": "True", "Use auto volts": "False"})
        t = sim_torch or SimTorch()
        # the sim's default material: cut volts on the sim torch's line at the cut height
        _set_prefs(prefs, "DEFAULT MATERIAL", {"Cut height": "1.5", "Pierce height": "3.0",
                                               "Pierce delay": "0.1", "Cut feed rate": "3000",
                                               "Cut volts": f"{t.v0 + t.k * 1.5:g}",
                                               "Kerf width": "1.0", "Cut mode": "1"})
    return ConfigResult(out, ini_out, src, sim, notes if thc == "distctrl" else [], hal_file)
