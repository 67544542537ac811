"""Route discovery and add-route over UDP port 48899, answered as a TwinCAT 3 target answers them.

What TwinCAT engineering ("Add Route Dialog", broadcast search), Beckhoff's ``adstool netid`` /
``addroute`` and pyads' ``adsGetNetIdForPLC`` / ``add_route_to_plc`` send before they use ADS over
TCP. Wire format (all integers little-endian)::

    magic 0x71146603 (4) | invoke id (4) | service id (4) | AMS NetId (6) | AMS port (2) | tag count (4)
    then per tag: tag id (2) | length (2) | data (length bytes)

Services: 1 = identify ("get NetId", server info), 6 = add route; a response carries the request's
service id with bit 31 set (0x80000001, 0x80000006), the request's invoke id, the target's NetId and
AMS port 10000 (the system service). Tags used here: 1 status (UDINT, an ADS error code), 2 password,
3 TwinCAT version (major, minor: 1 byte each; build: UINT), 4 OS version (an OSVERSIONINFO: size,
major, minor, build, platform id as UDINT, then 128 UTF-16 characters), 5 host name, 7 AMS NetId,
9 options, 12 route name, 13 user name; strings are NUL-terminated.

The identify answer carries the host name, the OS version and the TwinCAT version (the system
service's device info); the add-route answer carries one status tag. distctrl keeps no route table
and no user database: the allowed networks of the server (``--allow``) decide who may use ADS, so an
add-route is acknowledged without adding anything and its user name and password are not checked.
See docs/serve.md, "Route discovery and add-route (UDP 48899)".

The encoding and decoding functions are pure; :class:`DiscoveryResponder` is the asyncio datagram
endpoint that runs on an :class:`~distctrl.ads.server.AdsServer`'s event loop (``server.attached``).
Nothing a datagram contains raises out of it: malformed or short datagrams, unknown services and
responses are ignored (logged), and no answer depends on the size of what was sent.
"""
from __future__ import annotations

import asyncio
import ipaddress
import logging
import platform
import re
import socket
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

from .errors import ADSERR_DEVICE_INVALIDACCESS, ADSERR_DEVICE_INVALIDDATA, ERR_NOERROR
from .protocol import format_net_id, parse_net_id

if TYPE_CHECKING:  # pragma: no cover
    from .server import AdsServer

UDP_PORT = 48899                 # what every ADS client sends discovery and add-route to
MAGIC = 0x71146603
SERVICE_IDENTIFY = 1
SERVICE_ADD_ROUTE = 6
SERVICE_RESPONSE = 0x80000000
SYSTEM_SERVICE_PORT = 10000      # the AMS port a target names in its answers

TAG_STATUS = 1
TAG_PASSWORD = 2
TAG_TC_VERSION = 3
TAG_OS_VERSION = 4
TAG_HOST_NAME = 5
TAG_NET_ID = 7
TAG_OPTIONS = 9
TAG_ROUTE_NAME = 12
TAG_USER_NAME = 13

HEADER = struct.Struct("<III6sHI")   # magic, invoke id, service, AMS NetId, AMS port, tag count
HEADER_SIZE = HEADER.size            # 24
_TAG_HEAD = struct.Struct("<HH")
_OS_HEAD = struct.Struct("<5I")
OS_VERSION_SIZE = _OS_HEAD.size + 256    # 276: OSVERSIONINFO with a 128-character service-pack text
MAX_STRING = 255                     # longest string (bytes, without the NUL) put into an answer


class MalformedDatagram(ValueError):
    """A datagram that is not a well-formed message of this protocol (the reason is the text)."""


@dataclass(frozen=True)
class UdpMessage:
    """One datagram: header fields and its tags in wire order (a tag id may repeat)."""

    service: int
    net_id: bytes
    ams_port: int = SYSTEM_SERVICE_PORT
    tags: tuple[tuple[int, bytes], ...] = ()
    invoke_id: int = 0

    def tag(self, tag_id: int) -> bytes | None:
        """The data of the first tag ``tag_id``, None if there is none."""
        for t, data in self.tags:
            if t == tag_id:
                return data
        return None

    @property
    def is_response(self) -> bool:
        return bool(self.service & SERVICE_RESPONSE)


def decode(data: bytes) -> UdpMessage:
    """Parse one datagram. Raises :class:`MalformedDatagram` if it is shorter than the header, has
    another magic or announces more tags than it holds (a tag running past the end). Bytes after
    the announced tags are ignored."""
    data = bytes(data)
    if len(data) < HEADER_SIZE:
        raise MalformedDatagram(f"{len(data)} bytes, shorter than the {HEADER_SIZE}-byte header")
    magic, invoke_id, service, net_id, ams_port, count = HEADER.unpack_from(data)
    if magic != MAGIC:
        raise MalformedDatagram(f"magic 0x{magic:08X} is not 0x{MAGIC:08X}")
    tags, pos = [], HEADER_SIZE
    for i in range(count):       # each tag takes at least 4 bytes: the loop ends with the data
        if pos + _TAG_HEAD.size > len(data):
            raise MalformedDatagram(f"{count} tags announced, the datagram ends after {i}")
        tag_id, length = _TAG_HEAD.unpack_from(data, pos)
        pos += _TAG_HEAD.size
        if pos + length > len(data):
            raise MalformedDatagram(f"tag {tag_id} of {length} bytes runs past the end "
                                    f"({len(data) - pos} bytes left)")
        tags.append((tag_id, data[pos:pos + length]))
        pos += length
    return UdpMessage(service, net_id, ams_port, tuple(tags), invoke_id)


def encode(msg: UdpMessage) -> bytes:
    """The datagram of ``msg`` (tag data longer than 65535 bytes raises ``ValueError``)."""
    parts = [HEADER.pack(MAGIC, msg.invoke_id, msg.service, bytes(msg.net_id), msg.ams_port, len(msg.tags))]
    for tag_id, data in msg.tags:
        if len(data) > 0xFFFF:
            raise ValueError(f"tag {tag_id}: {len(data)} bytes, at most 65535")
        parts.append(_TAG_HEAD.pack(tag_id, len(data)) + bytes(data))
    return b"".join(parts)


# ------------------------------------------------------------------------------------------------
# tag values
# ------------------------------------------------------------------------------------------------
def string_tag(text: str) -> bytes:
    """A string tag's data: UTF-8, at most :data:`MAX_STRING` bytes, NUL-terminated."""
    raw = text.encode("utf-8", "replace")[:MAX_STRING]
    return raw.decode("utf-8", "ignore").encode("utf-8") + b"\0"     # never half a character


def tag_string(data: bytes | None) -> str:
    """The text of a string tag (up to its first NUL; undecodable bytes replaced)."""
    if data is None:
        return ""
    return bytes(data).split(b"\0", 1)[0].decode("utf-8", "replace")


def tc_version_tag(version: tuple[int, int, int]) -> bytes:
    """Tag 3: TwinCAT version, e.g. (3, 1, 4024) -> ``03 01 B8 0F``."""
    major, minor, build = version
    return struct.pack("<BBH", major, minor, build)


def os_version_tag(major: int, minor: int, build: int, platform_id: int, text: str) -> bytes:
    """Tag 4: OS version as an OSVERSIONINFO (276 bytes): its size, major, minor, build and platform
    id, then ``text`` as 128 UTF-16 characters (NUL-padded, at most 127 used)."""
    wide = text[:127].encode("utf-16-le", "replace")[:254]
    return _OS_HEAD.pack(OS_VERSION_SIZE, major, minor, build, platform_id) + wide.ljust(256, b"\0")


def host_os_version() -> tuple[int, int, int, int, str]:
    """(major, minor, build, platform id, text) of the computer distctrl runs on: the numbers of its
    kernel release (``6.1.0-18-amd64`` -> 6, 1, 0), platform id 0 (none of Windows' NT = 2 or CE = 3),
    the text ``"<system> <release>"``."""
    release = platform.release()
    numbers = [int(n) for n in re.findall(r"\d+", release)[:3]] + [0, 0, 0]
    major, minor, build = (min(n, 0xFFFFFFFF) for n in numbers[:3])
    return major, minor, build, 0, f"{platform.system()} {release}".strip()


@dataclass(frozen=True)
class TargetInfo:
    """What the target says about itself in the identify answer."""

    net_id: str
    host_name: str = field(default_factory=socket.gethostname)
    tc_version: tuple[int, int, int] = (3, 1, 4024)
    os_version: tuple[int, int, int, int, str] = field(default_factory=host_os_version)


@dataclass(frozen=True)
class RouteRequest:
    """The fields of an add-route request (service 6). The password is kept out of ``repr``."""

    route_name: str
    net_id: str | None          # the NetId the route is for (tag 7), None if missing or not 6 bytes
    address: str                # host name or IP of the computer the route points to (tag 5)
    user: str
    password: str = field(repr=False)
    temporary: bool = False     # tag 9, bit 0


def route_request(msg: UdpMessage) -> RouteRequest:
    """The fields of an add-route request (missing tags are empty)."""
    raw_id = msg.tag(TAG_NET_ID)
    options = msg.tag(TAG_OPTIONS) or b""
    return RouteRequest(
        route_name=tag_string(msg.tag(TAG_ROUTE_NAME)),
        net_id=format_net_id(raw_id) if raw_id is not None and len(raw_id) == 6 else None,
        address=tag_string(msg.tag(TAG_HOST_NAME)),
        user=tag_string(msg.tag(TAG_USER_NAME)),
        password=tag_string(msg.tag(TAG_PASSWORD)),
        temporary=len(options) >= 1 and bool(options[0] & 1))


def identify_response(request: UdpMessage, info: TargetInfo) -> bytes:
    """The answer to an identify request: our NetId and AMS port 10000 in the header, then the tags a
    TwinCAT 3 target sends, in its order: host name (5), OS version (4), TwinCAT version (3)."""
    major, minor, build, platform_id, text = info.os_version
    tags = ((TAG_HOST_NAME, string_tag(info.host_name)),
            (TAG_OS_VERSION, os_version_tag(major, minor, build, platform_id, text)),
            (TAG_TC_VERSION, tc_version_tag(info.tc_version)))
    return encode(UdpMessage(SERVICE_RESPONSE | SERVICE_IDENTIFY, parse_net_id(info.net_id),
                             SYSTEM_SERVICE_PORT, tags, request.invoke_id))


def add_route_response(request: UdpMessage, net_id: str, status: int) -> bytes:
    """The answer to an add-route request: one status tag (0 = route added, else an ADS error code;
    TwinCAT answers refused credentials with 0x704)."""
    return encode(UdpMessage(SERVICE_RESPONSE | SERVICE_ADD_ROUTE, parse_net_id(net_id), SYSTEM_SERVICE_PORT,
                             ((TAG_STATUS, struct.pack("<I", status)),), request.invoke_id))


class Answer(NamedTuple):
    """What :func:`answer` decided: the datagram to send back (None: no answer), a line for the log
    and its level."""

    datagram: bytes | None
    note: str
    level: int = logging.DEBUG


def answer(data: bytes, info: TargetInfo, is_allowed: Callable[[str], bool]) -> Answer:
    """The answer to one datagram of a client that may use the server. Never raises for any ``data``.

    * identify: :func:`identify_response`;
    * add route: status 0 (acknowledged; nothing is added: the allowed networks already decide who
      may connect, and user name and password are not checked), except 0x706 when the request names
      no NetId and 0x704 (access denied, what TwinCAT answers a refused route) when the route's
      address is an IP address outside ``is_allowed``: a connection from there would be refused;
    * anything else (malformed, a response, another service): no answer.
    """
    try:
        msg = decode(data)
    except MalformedDatagram as exc:
        return Answer(None, f"ignoring a malformed datagram ({len(data)} bytes): {exc}")
    if msg.is_response:
        return Answer(None, f"ignoring a response (service 0x{msg.service:08X})")
    if msg.service == SERVICE_IDENTIFY:
        return Answer(identify_response(msg, info), f"identify: answered NetId {info.net_id}")
    if msg.service == SERVICE_ADD_ROUTE:
        req = route_request(msg)
        what = f"add route {req.route_name!r} for NetId {req.net_id} at {req.address!r} (user {req.user!r})"
        if req.net_id is None:
            return Answer(add_route_response(msg, info.net_id, ADSERR_DEVICE_INVALIDDATA),
                          f"{what}: no NetId tag, answered 0x{ADSERR_DEVICE_INVALIDDATA:X}", logging.WARNING)
        if _is_ip(req.address) and not is_allowed(req.address):
            return Answer(add_route_response(msg, info.net_id, ADSERR_DEVICE_INVALIDACCESS),
                          f"{what}: refused, {req.address} is outside the allowed networks "
                          f"(answered 0x{ADSERR_DEVICE_INVALIDACCESS:X})", logging.WARNING)
        return Answer(add_route_response(msg, info.net_id, ERR_NOERROR),
                      f"{what}: acknowledged (no route table: the allowed networks decide; password not checked)",
                      logging.INFO)
    return Answer(None, f"ignoring unknown service 0x{msg.service:08X}")


def _is_ip(text: str) -> bool:
    try:
        ipaddress.ip_address(text.split("%", 1)[0])
    except ValueError:
        return False
    return True


# ------------------------------------------------------------------------------------------------
# the asyncio endpoint
# ------------------------------------------------------------------------------------------------
class DiscoveryResponder(asyncio.DatagramProtocol):
    """Answers discovery and add-route on UDP ``port`` of the server's ``host``, for the peers the
    server allows; others are ignored, counted in :attr:`refused` and logged ``refused <ip>``
    (at most once per address every ``log_interval`` seconds: UDP senders are cheap to forge).

    Attach it to an :class:`~distctrl.ads.server.AdsServer` before ``start()``
    (``server.attached.append(responder)``): it is opened on the server's loop after the TCP socket and
    closed at ``stop()``. If the port cannot be bound the server runs without it: one warning is
    logged and :attr:`error` says why (:attr:`address` stays None).

    Counters (read from any thread): :attr:`answered`, :attr:`refused`, :attr:`ignored`.
    """

    def __init__(self, info: TargetInfo, port: int = UDP_PORT, *, log_interval: float = 10.0) -> None:
        self.info = info
        self.port = int(port)
        self.log_interval = float(log_interval)
        self.address: tuple[str, int] | None = None      # where it listens, once open
        self.error: OSError | None = None
        self.answered = self.refused = self.ignored = 0
        self.server: AdsServer | None = None
        self.log = logging.getLogger("distctrl.ads")
        self._transport: asyncio.DatagramTransport | None = None
        self._last_refusal: dict[str, float] = {}

    # --- life cycle (on the server's loop) -------------------------------------------------------
    async def open(self, server: AdsServer) -> None:
        self.server, self.log = server, server.log
        self.error = None
        loop = asyncio.get_running_loop()
        try:
            transport, _ = await loop.create_datagram_endpoint(lambda: self, local_addr=(server.host, self.port))
        except OSError as exc:
            self.error = exc
            self.log.warning("ADS route discovery not answered: UDP %s:%d cannot be bound (%s); ADS over "
                             "TCP is served", server.host, self.port, exc.strerror or exc)
            return
        self._transport = transport  # type: ignore[assignment]
        sockname = transport.get_extra_info("sockname")
        self.address = (str(sockname[0]), int(sockname[1]))
        self.port = self.address[1]                      # port 0: the one the system picked
        self.log.info("ADS route discovery on UDP %s:%d", *self.address)

    def close(self) -> None:
        if self._transport is not None:
            self._transport.close()
        self._transport = None
        self.address = None

    # --- asyncio callbacks ---------------------------------------------------------------------
    def datagram_received(self, data: bytes, addr: Any) -> None:
        try:
            ip = str(addr[0])
            server = self.server
            if server is None or not server.is_allowed(ip):
                self.refused += 1
                now = time.monotonic()
                if now - self._last_refusal.get(ip, -1e9) >= self.log_interval:
                    if len(self._last_refusal) >= 1024:
                        self._last_refusal.clear()
                    self._last_refusal[ip] = now
                    self.log.warning("refused %s (UDP %d)", ip, self.port)
                return
            reply, note, level = answer(data, self.info, server.is_allowed)
            if reply is None:
                self.ignored += 1
            elif self._transport is not None:
                self._transport.sendto(reply, addr)
                self.answered += 1
            self.log.log(level, "UDP %d from %s: %s", self.port, ip, note)
        except Exception:  # pragma: no cover - a bug must not stop the loop
            self.log.exception("UDP %d: error while answering %r", self.port, addr)

    def error_received(self, exc: Exception) -> None:
        self.log.debug("UDP %d: %s", self.port, exc)     # e.g. ICMP port unreachable of a gone client
