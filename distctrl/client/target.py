"""The connection to an ADS target (a TwinCAT CNC, or ``distctrl serve``) through pyads.

Every failure becomes one :class:`MachineError` line that names what was being done, the ADS error
code and its meaning (``ADS error 0x7 (target machine not found - missing ADS route): ...``). Every
request is bounded: the TCP connect by ``connect_timeout`` (a probe before pyads is asked, so that an
unreachable host is an error in seconds, not the OS's minutes), every ADS request by pyads' timeout
(``timeout`` s, AdsSyncSetTimeoutEx).
"""
from __future__ import annotations

import ctypes
import ipaddress
import os
import socket
import sys
import time

from ..ads.errors import describe as _describe_device
from ..errors import DistCtrlError, ExitCode

#: the AMS port of the CNC's GEO task (the CNC objects, TF5200 / FCT-M3 §7.5; SPEC §10)
CNC_PORT = 551
#: the PLC's runtime port (HLI symbols)
PLC_PORT = 851
#: AMS/TCP: the port every ADS router listens on (TwinCAT's; ``--port`` for a target on another one)
AMS_TCP_PORT = 48898
#: client-side (AdsLib / router) error codes that are not device errors
CLIENT_CODES = {
    0x6: "target port not found - ADS server not started",
    0x7: "target machine not found - missing ADS route",
    0x745: "timeout elapsed - the target did not answer in time",
    0x746: "error in the client's socket subsystem",
    0x748: "ADS port not opened",
    0x74A: "no AMS address",
    0x750: "internal error in ADS sync",
    0x274C: "the host is unreachable",
    0x274D: "the connection attempt failed - the host did not respond",
}


def describe(code: int) -> str:
    """The meaning of an ADS error code (client/router codes first, then the device codes)."""
    if code in CLIENT_CODES:
        return CLIENT_CODES[code]
    try:
        # pyads (the [ads] extra): loaded only when a target is reached
        from pyads.errorcodes import ERROR_CODES
        if code in ERROR_CODES and ERROR_CODES[code]:
            return str(ERROR_CODES[code])
    except ImportError:            # pragma: no cover - the [ads] extra is missing
        pass
    return _describe_device(code)


class MachineError(DistCtrlError):
    """A failure talking to the target: one line for the user; ``code`` the ADS error code (or None
    for a socket-level failure), ``exit_code`` of the shared table."""

    def __init__(self, message: str, code: int | None = None, exit_code: ExitCode = ExitCode.INVALID_INPUT):
        self.code = code
        self.exit_code = exit_code
        if code is not None and code < 0:
            message = f"the ADS library failed (code {code}; the connection is broken): {message}"
        elif code is not None:
            message = f"ADS error 0x{code:X} ({describe(code)}): {message}"
        super().__init__(message)


def parse_target(ads: str, ip: str | None = None) -> tuple[str, int, str]:
    """``NETID[:PORT]`` and ``--ip`` -> (AMS NetId, AMS port, IP address). The port defaults to the
    CNC's 551; the IP to the NetId's first four numbers (TwinCAT's default NetId is the IP + .1.1)."""
    text = (ads or "").strip()
    net_id, sep, port_text = text.partition(":")
    parts = net_id.split(".")
    if len(parts) != 6 or not all(p.isdigit() and 0 <= int(p) <= 255 for p in parts):
        raise MachineError(f"--ads {ads!r}: an AMS NetId is six numbers 0-255 separated by dots, "
                           f"e.g. 5.12.34.56.1.1 (optionally :PORT, default {CNC_PORT})")
    port = CNC_PORT
    if sep:
        if not port_text.isdigit() or not 1 <= int(port_text) <= 65535:
            raise MachineError(f"--ads {ads!r}: the AMS port after ':' must be 1-65535")
        port = int(port_text)
    host = ip.strip() if ip else ".".join(parts[:4])
    bare, colon, tcp = host.rpartition(":")
    if colon and tcp.isdigit() and (":" not in bare or (bare.startswith("[") and bare.endswith("]"))):
        # HOST:PORT (or [v6]:PORT): the AMS/TCP port has its own option, which the route needs too
        raise MachineError(f"--ip {host!r}: the port does not go into --ip: give --ip {bare.strip('[]')} "
                           f"--port {tcp} (the target's AMS/TCP port; `distctrl serve --port N`: N)")
    try:
        ipaddress.ip_address(host)
    except ValueError:
        try:
            host = socket.gethostbyname(host)
        except OSError:
            raise MachineError(f"--ip {host!r}: not an IP address and not a host name that resolves") from None
    return net_id, port, host


def router_address(host: str, tcp_port: int = AMS_TCP_PORT) -> str:
    """The address pyads's router on Linux (Beckhoff's AdsLib) connects to: HOST for the standard AMS/TCP
    port 48898, else HOST:PORT ([v6]:PORT); AdsLib's AddRoute splits the port off (its
    ``bhf::ads::GetListOfAddresses(host, "48898")``; tested with pyads 3.6.0 against ``serve --port``)."""
    if tcp_port == AMS_TCP_PORT:
        return host
    return f"[{host}]:{tcp_port}" if ":" in host and not host.startswith("[") else f"{host}:{tcp_port}"


def quiet_adslib() -> None:
    """pyads' AdsLib logs on the process's stderr (``Warning: Socket(): connect failed``, ``Info:
    connection closed by remote``, ``Error: write frame failed``); our own one-line message says what
    happened. In a real process (stderr is file descriptor 2) Python's stderr moves to a copy of it and
    descriptor 2 to /dev/null, unless DISTCTRL_ADS_LOG=1 asks for the library's lines."""
    if os.environ.get("DISTCTRL_ADS_LOG") == "1" or getattr(quiet_adslib, "done", False):
        return
    try:
        if sys.stderr.fileno() != 2:
            return
        sys.stderr.flush()
        saved = os.dup(2)
        sys.stderr = os.fdopen(saved, "w", buffering=1, encoding=sys.stderr.encoding,
                               errors="backslashreplace")
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 2)
        os.close(null)
    except (AttributeError, OSError, ValueError):
        return
    quiet_adslib.done = True


class _quiet_stderr:
    """File descriptor 2 to /dev/null for a moment (the C library's own log lines, not ours)."""

    def __enter__(self):
        try:
            sys.stderr.flush()
            self.saved = os.dup(2)
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, 2)
            os.close(null)
        except OSError:
            self.saved = None
        return self

    def __exit__(self, *exc):
        if self.saved is not None:
            os.dup2(self.saved, 2)
            os.close(self.saved)


def _pyads():
    try:
        # pyads (the [ads] extra): loaded only when a target is reached
        import pyads
    except ImportError:            # pragma: no cover - the [ads] extra is missing
        raise MachineError("the ADS client needs pyads: pip install 'distctrl[ads]'") from None
    return pyads


class Target:
    """An open ADS connection to one AMS port of the target (a context manager).

    ``read(ig, io, n)`` / ``write(ig, io, data)`` move raw bytes; every failure is a
    :class:`MachineError` that says ``what`` was being done."""

    def __init__(self, net_id: str, port: int = CNC_PORT, ip: str = "127.0.0.1", *, timeout: float = 2.0,
                 connect_timeout: float = 3.0, local_net_id: str | None = None, tcp_port: int = AMS_TCP_PORT):
        self.net_id, self.port, self.ip = net_id, int(port), ip
        self.tcp_port = int(tcp_port)
        self.timeout, self.connect_timeout = float(timeout), float(connect_timeout)
        self.local_net_id = local_net_id
        self.conn = None

    @property
    def address(self) -> str:
        at = self.ip if self.tcp_port == AMS_TCP_PORT else f"{self.ip} (AMS/TCP port {self.tcp_port})"
        return f"{self.net_id}:{self.port} at {at}"

    def open(self) -> "Target":
        # a bounded TCP probe first: AdsLib's own connect can wait the OS's full SYN timeout
        try:
            with socket.create_connection((self.ip, self.tcp_port), timeout=self.connect_timeout):
                pass
        except socket.timeout:
            raise MachineError(f"target {self.ip}:{self.tcp_port} not reachable (no answer within "
                               f"{self.connect_timeout:g} s): check the IP, the network and the firewall "
                               f"(TCP {self.tcp_port})") from None
        except OSError as exc:
            serve_port = "" if self.tcp_port == AMS_TCP_PORT else f" --port {self.tcp_port}"
            raise MachineError(f"target {self.ip}:{self.tcp_port} not reachable ({exc.strerror or exc}): "
                               f"is TwinCAT (or distctrl serve{serve_port}) running there?") from None
        pyads = _pyads()
        try:
            if self.local_net_id:
                pyads.set_local_address(self.local_net_id)
            conn = pyads.Connection(self.net_id, self.port, router_address(self.ip, self.tcp_port))
            conn.open()
            conn.set_timeout(max(1, int(self.timeout * 1000)))
        except pyads.ADSError as exc:
            raise MachineError(f"opening {self.address}", code=exc.err_code) from None
        except (OSError, RuntimeError) as exc:
            raise MachineError(f"opening {self.address}: {exc}") from None
        self.conn = conn
        # a first request: an AMS port that is not open, or a missing route, shows here
        self.state(f"reading the ADS state of {self.address}")
        return self

    def close(self) -> None:
        conn, self.conn = self.conn, None
        if conn is not None:
            with _quiet_stderr():  # AdsLib's receive thread logs "connection closed by remote" on stderr
                try:
                    conn.close()
                except Exception:  # noqa: BLE001 - closing a broken connection must not hide the error
                    pass

    def __enter__(self) -> "Target":
        return self.open() if self.conn is None else self

    def __exit__(self, *exc) -> None:
        self.close()

    def _call(self, what: str, fn, *args):
        if self.conn is None:
            raise MachineError(f"{what}: the connection to {self.address} is not open")
        pyads = _pyads()
        try:
            return fn(*args)
        except pyads.ADSError as exc:
            raise MachineError(what, code=exc.err_code) from None
        except (OSError, RuntimeError, ValueError, TypeError) as exc:
            raise MachineError(f"{what}: {exc}") from None

    def state(self, what: str = "reading the ADS state") -> tuple[int, int]:
        return self._call(what, self.conn.read_state)

    def read(self, index_group: int, index_offset: int, length: int, what: str) -> bytes:
        raw = self._call(what, self.conn.read, index_group, index_offset, ctypes.c_uint8 * length)
        data = bytes(raw)
        if len(data) != length:
            raise MachineError(f"{what}: the target answered {len(data)} bytes, {length} expected")
        return data

    def write(self, index_group: int, index_offset: int, data: bytes, what: str) -> None:
        self._call(what, self.conn.write, index_group, index_offset, list(bytes(data)), ctypes.c_uint8 * len(data))


def wait_until(predicate, timeout: float, interval: float = 0.02) -> bool:
    """Poll ``predicate`` until true or ``timeout`` s passed."""
    deadline = time.monotonic() + timeout
    while True:
        if predicate():
            return True
        if time.monotonic() >= deadline:
            return False
        time.sleep(interval)
