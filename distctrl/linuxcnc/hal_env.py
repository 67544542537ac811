"""The HAL session of the bench (docs/linuxcnc.md "How it runs").

Debian's ``linuxcnc-uspace`` runs HAL without a real-time kernel. As root, ``rtapi_app`` needs an
unprivileged uid (``RTAPI_UID``) and a socket path that uid can write (``RTAPI_FIFO_PATH``); this module
sets both (the uid of ``nobody`` unless ``RTAPI_UID`` is set). HAL's shared memory is one per machine,
so one session at a time: :class:`HalSession` holds a lock file for its lifetime, and it never touches a
HAL it did not start (a running LinuxCNC's: it refuses).

Errors here are edge errors (:class:`LinuxCNCError`): a missing package, a component that does not
build, a halcmd line that fails - each message names what failed and how to fix it.
"""
from __future__ import annotations

import fcntl
import hashlib
import json
import os
import pwd
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

__all__ = ["LinuxCNCError", "HalSession", "hal_environment", "require_linuxcnc", "install_component",
           "build_component", "sudo_command", "COMPONENTS", "import_hal", "hal_processes",
           "session_lock_path"]

HAL_DIR = Path(__file__).resolve().parent / "hal"
#: the components distctrl builds with halcompile (hal/<name>.comp): the bench's gate, the law, the
#: QtPlasmaC glue and the sim torch of `distctrl linuxcnc config`
COMPONENTS = ("distctrl_lockstep", "distctrl_thc", "distctrl_qtplasmac",
              "distctrl_simtorch")
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


def build_component(name: str, force: bool = False) -> tuple[Path, bool]:
    """Build ``hal/<name>.comp`` with halcompile and install it into LinuxCNC's module directory (rtapi_app
    loads modules only from there; the new file is renamed over the old one, so a running session keeps
    the module it loaded). Skipped when the installed module was built from this very source: the module
    directory is one per machine, shared by every checkout, so the source's SHA-256 is kept beside the
    module (``.<name>.so.src-sha256``) and compared, not file times. Returns the module and whether it
    was built (False: skipped, the installed one is from the same source)."""
    require_linuxcnc(dev=True)
    src = HAL_DIR / f"{name}.comp"
    target = MODULE_DIR / f"{name}.so"
    stamp = MODULE_DIR / f".{name}.so.src-sha256"
    digest = hashlib.sha256(src.read_bytes()).hexdigest()
    if not force and target.exists() and stamp.exists() and stamp.read_text().strip() == digest:
        return target, False
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
            raise LinuxCNCError(f"cannot install {target} ({exc.strerror}): root is needed to write "
                                f"{MODULE_DIR}: {sudo_command()}") from None
    return target, True


def install_component(name: str, force: bool = False) -> Path:
    """:func:`build_component` for callers that need only the module's path."""
    return build_component(name, force)[0]


def sudo_command(args: str = "linuxcnc build") -> str:
    """The command that runs this distctrl as root: sudo resets PATH (secure_path), so a distctrl
    installed in a venv is not found by ``sudo distctrl``; its Python's absolute path is."""
    return f"sudo {sys.executable} -m distctrl {args}"




#: processes of a running LinuxCNC (its task, server, halui, io) and of any HAL (rtapi_app, the realtime
#: side every HAL session has in Debian's uspace build): the bench never touches a HAL it did not start
_FOREIGN_COMMS = ("rtapi_app", "linuxcncsvr", "milltask", "halui", "io", "iocontrol", "linuxcnc")


def _proc_starttime(pid: int) -> int | None:
    """A process's start time (clock ticks since boot, /proc/PID/stat field 22): with the pid it tells a
    process from a later one that reuses the pid; None if the process is gone."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return int(stat[stat.rindex(")") + 2:].split()[19])


def hal_processes() -> list[tuple[int, str]]:
    """(pid, name) of every running LinuxCNC or HAL process (``_FOREIGN_COMMS``), by /proc/PID/comm."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            comm = (entry / "comm").read_text().strip()
        except OSError:
            continue
        if comm in _FOREIGN_COMMS:
            found.append((int(entry.name), comm))
    return sorted(found)


def _lock_holder(path: Path) -> str:
    """Who holds the session lock: the pid the holder wrote into it, with its command line if it runs."""
    try:
        pid = int(path.read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return "holder unknown"
    try:
        cmd = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace").strip()
    except OSError:
        return f"pid {pid}"
    return f"pid {pid}: {cmd[:80]}"


def session_lock_path() -> Path:
    """The machine-wide lock of HAL sessions (one HAL per machine): the bench, the tests and the
    `distctrl linuxcnc` sim runs hold it while their HAL lives."""
    return _RUN_DIR / "session.lock"


def _stderr(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


class HalSession:
    """One HAL instance for a bench run: ``with HalSession() as hs: hs.cmd("loadrt ...")``.

    It never touches a HAL it did not start (docs/linuxcnc.md "What you need"): after taking the
    machine-wide lock (saying that it waits, for what and how long), it refuses with one line while
    LinuxCNC or another HAL runs (:func:`hal_processes`), after ``foreign_grace`` s (a HAL whose session
    has just released the lock may still be exiting). Its own rtapi_app (pid and start time) is
    written to ``session.json`` beside the lock; on exit it unloads the HAL (``halrun -U``) only if
    that rtapi_app is the one running. A leftover of its own killed run (the recorded rtapi_app, still
    running, its recording process gone) is unloaded at the next start, and said so."""

    def __init__(self, lock_timeout: float = 600.0, notify=None, foreign_grace: float = 15.0):
        require_linuxcnc()
        self.env = hal_environment()
        self.lock_timeout = lock_timeout
        self.notify = notify or _stderr
        self.foreign_grace = foreign_grace
        self._lock = None
        self._locked = False
        self._rtapi: tuple[int, int] | None = None     # our rtapi_app: (pid, start time)
        self.log: list[str] = []

    def __enter__(self) -> "HalSession":
        _RUN_DIR.mkdir(mode=0o755, exist_ok=True)
        path = session_lock_path()
        self._lock = open(path, "a+")
        t0 = time.monotonic()
        said = False
        try:
            while True:
                try:
                    fcntl.flock(self._lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
                    self._locked = True
                    break
                except BlockingIOError:
                    if not said:
                        self.notify(f"waiting for another HAL session to end (lock {path}, held by "
                                    f"{_lock_holder(path)}): up to {self.lock_timeout:g} s")
                        said = True
                    if time.monotonic() - t0 > self.lock_timeout:
                        raise LinuxCNCError(f"another HAL session held {path} ({_lock_holder(path)}) for "
                                            f"more than {self.lock_timeout:g} s") from None
                    time.sleep(0.2)
            if said:
                self.notify(f"lock {path} taken after {time.monotonic() - t0:.0f} s")
            self._lock.seek(0)
            self._lock.truncate()
            self._lock.write(f"{os.getpid()}\n")
            self._lock.flush()
            self._refuse_foreign_hal()
        except BaseException:
            self._release()
            raise
        return self

    def _record_path(self) -> Path:
        return _RUN_DIR / "session.json"

    def _refuse_foreign_hal(self) -> None:
        running = hal_processes()
        t0 = time.monotonic()
        # a HAL whose session has just ended (its lock released) may take seconds to exit: wait for it
        # (foreign_grace), then refuse what still runs
        while running and time.monotonic() - t0 < self.foreign_grace and not self._leftover_of_ours(running):
            time.sleep(0.2)
            running = hal_processes()
        if not running:
            return
        rtapi = [pid for pid, name in running if name == "rtapi_app"]
        if self._leftover_of_ours(running):
            self.notify(f"unloading the HAL a killed distctrl session left behind (rtapi_app pid {rtapi[0]}, "
                        f"recorded in {self._record_path()})")
            self._unload(rtapi[0])
            self._record_path().unlink(missing_ok=True)
            return
        what = ", ".join(f"{name} (pid {pid})" for pid, name in running)
        raise LinuxCNCError(f"a HAL that distctrl did not start is running: {what}; distctrl never stops or "
                            "unloads it: quit LinuxCNC (or halrun) first, or run this on another PC")

    def _leftover_of_ours(self, running: list[tuple[int, str]]) -> bool:
        """Only a recorded rtapi_app of ours (pid and start time), its recording process gone, runs."""
        record = self._read_record()
        rtapi = [pid for pid, name in running if name == "rtapi_app"]
        return (len(running) == 1 and record is not None and len(rtapi) == 1
                and rtapi[0] == record.get("rtapi_pid")
                and _proc_starttime(rtapi[0]) == record.get("rtapi_start")
                and _proc_starttime(int(record.get("owner_pid", 0))) != record.get("owner_start"))

    def _read_record(self) -> dict | None:
        try:
            return json.loads(self._record_path().read_text())
        except (OSError, ValueError):
            return None

    def _note_rtapi(self) -> None:
        """Record the rtapi_app the first loadrt started (ours: nothing ran before, the lock is held)."""
        if self._rtapi is not None:
            return
        rtapi = [pid for pid, name in hal_processes() if name == "rtapi_app"]
        if len(rtapi) == 1 and (start := _proc_starttime(rtapi[0])) is not None:
            self._rtapi = (rtapi[0], start)
            self._record_path().write_text(json.dumps({
                "rtapi_pid": rtapi[0], "rtapi_start": start, "owner_pid": os.getpid(),
                "owner_start": _proc_starttime(os.getpid())}))

    def __exit__(self, *exc) -> None:
        try:
            self._note_rtapi()
            if self._rtapi is not None and _proc_starttime(self._rtapi[0]) == self._rtapi[1]:
                self._unload()                        # the HAL this session started, and only that
            self._record_path().unlink(missing_ok=True)
        finally:
            self._release()

    def _release(self) -> None:
        if self._lock is not None:
            if self._locked:
                self._lock.truncate(0)                # no stale holder pid for the next waiter
                self._locked = False
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

    def _unload(self, pid: int | None = None) -> None:
        """``halrun -U``, then wait (up to 30 s) until rtapi_app ``pid`` has gone: a session started while
        it still shuts down fails ("rtapi_app exited without becoming ready")."""
        pid = pid if pid is not None else (self._rtapi[0] if self._rtapi else None)
        self._run(["halrun", "-U"], timeout=60.0)
        t0 = time.monotonic()
        while pid is not None and _proc_starttime(pid) is not None and time.monotonic() - t0 < 30.0:
            time.sleep(0.05)

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
        self._note_rtapi()
        if rc != 0:
            raise LinuxCNCError("halcmd failed:\n  " + "\n  ".join(lines) + f"\n{text.strip()}")
        return text

    def getp(self, name: str) -> str:
        """A pin's or parameter's value as halcmd prints it (``getp``)."""
        return self.cmd(f"getp {name}").strip()
