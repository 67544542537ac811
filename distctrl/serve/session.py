"""How a served session runs in the foreground: until a duration, Ctrl-C or SIGTERM (``systemctl stop``,
``docker stop``, ``kill``), each a normal end (docs/serve.md). ``distctrl serve`` and ``distctrl ui``
(:mod:`distctrl.cli.serve`) run their sessions with :func:`run_until`."""
from __future__ import annotations

import signal
import threading
import time

__all__ = ["catch_sigterm", "restore_sigterm", "run_until"]

#: set by the SIGTERM handler of a running session
_TERMINATED: dict = {"by": None}


def _on_sigterm(signum, frame) -> None:          # noqa: ARG001 (the signal module's signature)
    _TERMINATED["by"] = "SIGTERM"


def catch_sigterm():
    """SIGTERM ends the session as Ctrl-C does (the report, the JSON, the servers stopped, exit 0)
    instead of killing the process; returns the previous handler (None where none can be set: only
    the main thread may)."""
    _TERMINATED["by"] = None
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, _on_sigterm)


def restore_sigterm(previous) -> None:
    """Put back the SIGTERM handler :func:`catch_sigterm` replaced."""
    if previous is not None:
        signal.signal(signal.SIGTERM, previous)


def run_until(served, duration: float | None) -> str:
    """Wait while ``served`` (a started :class:`~distctrl.serve.machine.ServedMachine`) runs: until
    ``duration`` seconds (None: no limit), Ctrl-C or SIGTERM (after :func:`catch_sigterm`). Returns what
    stopped it: ``"duration"``, ``"SIGINT"`` or ``"SIGTERM"``; an error of the cycle thread is raised."""
    try:
        t_end = None if duration is None else time.monotonic() + duration
        while t_end is None or time.monotonic() < t_end:
            time.sleep(0.2)
            if served.loop.error is not None:
                raise served.loop.error
            if _TERMINATED["by"] is not None:
                return _TERMINATED["by"]
    except KeyboardInterrupt:
        return "SIGINT"
    return "duration"
