"""A LinuxCNC configuration run headless (Xvfb) for a test (docs/linuxcnc.md "Tests").

:class:`LinuxCNCRun` starts ``linuxcnc INI`` on a display of its own Xvfb inside a :class:`HalSession`
(the machine-wide HAL lock; it refuses while another LinuxCNC or HAL runs) and stops everything it
started, by pid: the GUI (qtvcp ignores SIGTERM: SIGKILL), then the ``linuxcnc`` script, which shuts its
HAL down; what is left of its process group after 60 s is killed; then Xvfb. LinuxCNC's own lock file
(``/tmp/linuxcnc.lock``, which makes the next start wait on a dialog) is removed if this run made it.
``drive(...)`` runs sim_drive.py with Debian's python3 (LinuxCNC's ``linuxcnc`` and ``hal`` modules).
"""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import time
from pathlib import Path

from .hal_env import HalSession, LinuxCNCError

__all__ = ["LinuxCNCRun", "DRIVER"]

DRIVER = Path(__file__).resolve().parent / "sim_drive.py"
LINUXCNC_LOCK = Path("/tmp/linuxcnc.lock")
SYSTEM_PYTHON = "/usr/bin/python3"


def _children(pid: int) -> list[int]:
    out = subprocess.run(["ps", "-o", "pid=", "--ppid", str(pid)], capture_output=True, text=True).stdout
    kids = [int(p) for p in out.split()]
    return kids + [g for k in kids for g in _children(k)]


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return ""


class LinuxCNCRun:
    """``with LinuxCNCRun(ini, logdir) as run: run.wait_ready(); run.drive(program, out)``."""

    def __init__(self, ini: str | Path, logdir: str | Path, ready_signal: str = "dthc:led-enabled",
                 notify=None):
        for tool in ("linuxcnc", "Xvfb", "halcmd"):
            if not shutil.which(tool):
                raise LinuxCNCError(f"{tool} not found: apt-get install -y linuxcnc-uspace xvfb "
                                    "(`make linuxcnc`)")
        self.ini = Path(ini).resolve()
        self.logdir = Path(logdir)
        self.logdir.mkdir(parents=True, exist_ok=True)
        self.ready_signal = ready_signal
        self.notify = notify
        self.hal: HalSession | None = None
        self.xvfb: subprocess.Popen | None = None
        self.lcnc: subprocess.Popen | None = None
        self._made_lock = False
        self.env: dict = {}

    def __enter__(self) -> "LinuxCNCRun":
        self.hal = HalSession(notify=self.notify)
        self.hal.__enter__()
        try:
            if LINUXCNC_LOCK.exists():
                raise LinuxCNCError(f"{LINUXCNC_LOCK} exists: another LinuxCNC runs, or a killed one left it "
                                    "(remove it if no LinuxCNC runs)")
            r, w = os.pipe()
            self.xvfb = subprocess.Popen(["Xvfb", "-displayfd", str(w), "-screen", "0", "1600x1000x24",
                                          "-nolisten", "tcp"], pass_fds=(w,), stdin=subprocess.DEVNULL,
                                         stdout=subprocess.DEVNULL,
                                         stderr=open(self.logdir / "xvfb.log", "w"))
            os.close(w)
            with os.fdopen(r) as f:
                display = f.readline().strip()
            if not display.isdigit():
                raise LinuxCNCError("Xvfb did not start (see xvfb.log)")
            self.env = dict(self.hal.env, DISPLAY=f":{display}")
            self.lcnc = subprocess.Popen(["linuxcnc", str(self.ini)], cwd=self.ini.parent, env=self.env,
                                         stdin=subprocess.DEVNULL,
                                         stdout=open(self.logdir / "linuxcnc.log", "w"),
                                         stderr=subprocess.STDOUT, start_new_session=True)
            self._made_lock = True
        except BaseException:
            self.__exit__(None, None, None)
            raise
        return self

    def halcmd(self, *args: str, timeout: float = 30.0) -> subprocess.CompletedProcess:
        return subprocess.run(["halcmd", *args], env=self.env, capture_output=True, text=True,
                              stdin=subprocess.DEVNULL, timeout=timeout)

    def wait_ready(self, timeout: float = 300.0) -> None:
        """Until the last POSTGUI file has run (its ``ready_signal`` exists) and halui is up."""
        t0 = time.monotonic()
        while time.monotonic() - t0 < timeout:
            dialog = any("show_errors" in _cmdline(p) for p in _children(self.lcnc.pid))
            if self.lcnc.poll() is not None or dialog:        # its error dialog: it failed to start
                tail = (self.logdir / "linuxcnc.log").read_text(errors="replace").strip().splitlines()[-3:]
                raise LinuxCNCError(f"LinuxCNC failed to start ({self.logdir / 'linuxcnc.log'}): "
                                    + " | ".join(tail))
            sig = self.halcmd("show", "sig", self.ready_signal)
            if sig.returncode == 0 and self.ready_signal in sig.stdout and \
                    self.halcmd("getp", "halui.machine.is-on").returncode == 0:
                return
            time.sleep(1.0)
        raise LinuxCNCError(f"LinuxCNC not ready within {timeout:g} s: {self.logdir / 'linuxcnc.log'}")

    def drive(self, program: str | Path, samples: str | Path, pins: list[str], max_seconds: float = 180.0,
              actions: list | None = None, pause_grace: float = 8.0) -> dict:
        """sim_drive.py: E-stop off, machine on, home, torch enable, run ``program``, sample ``pins``."""
        spec = {"program": str(Path(program).resolve()), "samples": str(samples), "pins": pins,
                "max_seconds": max_seconds, "actions": actions or [],
                "pause_grace": pause_grace}
        p = subprocess.run([SYSTEM_PYTHON, str(DRIVER), json.dumps(spec)], env=self.env, capture_output=True,
                           text=True, stdin=subprocess.DEVNULL, timeout=max_seconds + 240)
        (self.logdir / "drive.log").write_text(p.stdout + p.stderr)
        lines = [ln for ln in p.stdout.splitlines() if ln.startswith("{")]
        if p.returncode != 0 or not lines:
            raise LinuxCNCError(f"sim_drive.py failed ({p.returncode}): {(p.stderr or p.stdout)[-600:]}")
        return json.loads(lines[-1])

    def __exit__(self, *exc) -> None:
        try:
            if self.lcnc is not None:
                for pid in [p for p in _children(self.lcnc.pid) if "qtvcp" in _cmdline(p)]:
                    os.kill(pid, signal.SIGKILL)       # qtvcp ignores SIGTERM; the script then shuts HAL down
                try:
                    self.lcnc.wait(60)
                except subprocess.TimeoutExpired:
                    self.lcnc.terminate()
                    try:
                        self.lcnc.wait(30)
                    except subprocess.TimeoutExpired:
                        os.killpg(self.lcnc.pid, signal.SIGKILL)   # the session this run started
                        self.lcnc.wait(10)
            if self.xvfb is not None:
                self.xvfb.terminate()
                self.xvfb.wait(30)
        finally:
            if self._made_lock:
                LINUXCNC_LOCK.unlink(missing_ok=True)
            if self.hal is not None:
                self.hal.__exit__(None, None, None)
                self.hal = None
