"""The HAL session of the bench (docs/linuxcnc.md "How it runs").

Debian's ``linuxcnc-uspace`` runs HAL without a real-time kernel. As root, ``rtapi_app`` needs an
unprivileged uid (``RTAPI_UID``) and a socket path that uid can write (``RTAPI_FIFO_PATH``); this module
sets both (the uid of ``nobody`` unless ``RTAPI_UID`` is set). HAL's shared memory is one per machine,
so one session at a time: :class:`HalSession` holds a lock file for its lifetime.

Errors here are edge errors (:class:`LinuxCNCError`): a missing package, a component that does not
build, a halcmd line that fails - each message names what failed and how to fix it.
"""
from __future__ import annotations

import fcntl
import hashlib
import os
import pwd
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

__all__ = ["LinuxCNCError", "HalSession", "hal_environment", "require_linuxcnc", "install_component",
           "COMPONENTS", "import_hal"]

HAL_DIR = Path(__file__).resolve().parent / "hal"
#: the components distctrl builds with halcompile (hal/<name>.comp)
COMPONENTS = ("distctrl_lockstep", "distctrl_thc")
MODULE_DIR = Path("/usr/lib/linuxcnc/modules")
_RUN_DIR = Path(tempfile.gettempdir()) / "distctrl-linuxcnc"
_DIST_PACKAGES = "/usr/lib/python3/dist-packages"


class LinuxCNCError(Exception):
    """An edge error of the LinuxCNC bench (exit code 1: the environment or an input is not usable)."""


def require_linuxcnc(dev: bool = False) -> None:
    """Raise :class:`LinuxCNCError` unless halrun (and halcompile with ``dev``) are installed."""
    missing = [tool for tool in ("halrun", "halcmd") + (("halcompile",) if dev else ()) if not shutil.which(tool)]
    if missing:
        pkg = "linuxcnc-uspace linuxcnc-uspace-dev" if dev else "linuxcnc-uspace"
        raise LinuxCNCError(f"{', '.join(missing)} not found: install Debian's LinuxCNC "
                            f"(apt-get install -y {pkg}; `make linuxcnc` does it)")


def hal_environment() -> dict:
    """os.environ with RTAPI_UID / RTAPI_FIFO_PATH set as halrun needs them when run as root."""
    env = dict(os.environ)
    if os.geteuid() == 0:
        uid = env.get("RTAPI_UID") or str(pwd.getpwnam("nobody").pw_uid)
        env["RTAPI_UID"] = uid
        _RUN_DIR.mkdir(mode=0o755, exist_ok=True)
        os.chown(_RUN_DIR, int(uid), -1)
        env.setdefault("RTAPI_FIFO_PATH", str(_RUN_DIR / "rtapi_fifo"))
    return env


def import_hal():
    """LinuxCNC's Python ``hal`` module (Debian installs it for the system's Python 3; a venv of the
    same Python version can use it: its directory is appended to sys.path, after everything else)."""
    try:
        import hal  # noqa: F401
    except ImportError:
        if _DIST_PACKAGES not in sys.path:
            sys.path.append(_DIST_PACKAGES)
        try:
            import hal  # noqa: F401
        except ImportError as exc:
            raise LinuxCNCError(f"LinuxCNC's Python hal module cannot be imported ({exc}): install "
                                "linuxcnc-uspace for this Python (Debian's python3)") from None
    return sys.modules["hal"]


def install_component(name: str, force: bool = False) -> Path:
    """Build ``hal/<name>.comp`` with halcompile and install it into LinuxCNC's module directory (rtapi_app
    loads modules only from there; the new file is renamed over the old one, so a running session keeps
    the module it loaded). Skipped when the installed module was built from this very source: the module
    directory is one per machine, shared by every checkout, so the source's SHA-256 is kept beside the
    module (``.<name>.so.src-sha256``) and compared, not file times."""
    require_linuxcnc(dev=True)
    src = HAL_DIR / f"{name}.comp"
    target = MODULE_DIR / f"{name}.so"
    stamp = MODULE_DIR / f".{name}.so.src-sha256"
    digest = hashlib.sha256(src.read_bytes()).hexdigest()
    if not force and target.exists() and stamp.exists() and stamp.read_text().strip() == digest:
        return target
    with tempfile.TemporaryDirectory(prefix="distctrl-halcompile-") as tmp:
        shutil.copy(src, tmp)
        p = subprocess.run(["halcompile", "--compile", f"{name}.comp"], cwd=tmp, stdin=subprocess.DEVNULL,
                           capture_output=True, text=True)
        if p.returncode != 0:
            raise LinuxCNCError(f"halcompile --compile {src} failed (exit {p.returncode}):\n{p.stdout}{p.stderr}")
        # a new file renamed over the old one: a running rtapi_app keeps the module it has mapped
        try:
            partial = MODULE_DIR / f".{name}.so.{os.getpid()}"
            shutil.copy(Path(tmp) / f"{name}.so", partial)
            os.replace(partial, target)
            partial_stamp = MODULE_DIR / f".{name}.so.src-sha256.{os.getpid()}"
            partial_stamp.write_text(digest + "\n")
            os.replace(partial_stamp, stamp)
        except OSError as exc:
            raise LinuxCNCError(f"cannot install {target} ({exc.strerror}; root is needed to write "
                                f"{MODULE_DIR})") from None
    return target


class HalSession:
    """One HAL instance for a bench run: ``with HalSession() as hs: hs.cmd("loadrt ...")``. On exit the
    threads stop and everything is unloaded (``halrun -U``). Holds a machine-wide lock (one HAL per
    machine)."""

    def __init__(self, lock_timeout: float = 600.0):
        require_linuxcnc()
        self.env = hal_environment()
        self.lock_timeout = lock_timeout
        self._lock = None
        self.log: list[str] = []

    def __enter__(self) -> "HalSession":
        _RUN_DIR.mkdir(mode=0o755, exist_ok=True)
        self._lock = open(_RUN_DIR / "session.lock", "w")
        t0 = time.monotonic()
        while True:
            try:
                fcntl.flock(self._lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() - t0 > self.lock_timeout:
                    raise LinuxCNCError(f"another HAL session holds {_RUN_DIR / 'session.lock'} for more than "
                                        f"{self.lock_timeout:g} s") from None
                time.sleep(0.2)
        self._unload()                                # a session a killed run left behind
        return self

    def __exit__(self, *exc) -> None:
        try:
            self._unload()
        finally:
            if self._lock is not None:
                self._lock.close()
                self._lock = None

    def _run(self, argv: list[str], timeout: float = 60.0) -> tuple[int, str]:
        # rtapi_app, which the first loadrt starts, inherits halcmd's stdout: a pipe would never close
        with tempfile.TemporaryFile("w+") as out:
            try:
                p = subprocess.run(argv, env=self.env, stdin=subprocess.DEVNULL, stdout=out,
                                   stderr=subprocess.STDOUT, timeout=timeout)
            except subprocess.TimeoutExpired:
                raise LinuxCNCError(f"{' '.join(argv)} did not finish within {timeout:g} s (a HAL session that a "
                                    "killed process left behind? run `halrun -U` as root and try again)") from None
            out.seek(0)
            text = "".join(line for line in out if "fallback_uid" not in line and "POSIX non-realtime" not in line)
        return p.returncode, text

    def _unload(self) -> None:
        self._run(["halrun", "-U"], timeout=60.0)

    def cmd(self, *lines: str, ini: str | None = None) -> str:
        """Run halcmd lines (one halcmd process, -k: all lines are tried; ``ini``: an INI file for
        ``[SECTION]KEY`` substitutions, as halrun -i); raise on any failure."""
        with tempfile.NamedTemporaryFile("w", suffix=".hal", delete=False) as f:
            f.write("\n".join(lines) + "\n")
            path = f.name
        try:
            rc, text = self._run(["halcmd", *(["-i", ini] if ini else []), "-k", "-f", path])
        finally:
            os.unlink(path)
        self.log.extend(lines)
        if rc != 0:
            raise LinuxCNCError("halcmd failed:\n  " + "\n  ".join(lines) + f"\n{text.strip()}")
        return text

    def getp(self, name: str) -> str:
        """A pin's or parameter's value as halcmd prints it (``getp``)."""
        return self.cmd(f"getp {name}").strip()
