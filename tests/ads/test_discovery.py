"""Route discovery and add-route over UDP 48899 (issue 14): the codec at known bytes, the responder on
an AdsServer (allowed and foreign clients, garbage, a port that cannot be bound) and pyads' real
functions against a served machine on 127.0.0.1:48899."""
from __future__ import annotations

import ipaddress
import logging
import random
import socket
import struct
from pathlib import Path

import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from distctrl.ads import AdsServer
from distctrl.ads import discovery as D
from distctrl.ads import errors as E
from distctrl.ads import protocol as P
from distctrl.ads.devices import serve_over_ads
from distctrl.sim.scenario import load_scenario

from . import MemoryDevice, RawClient, wait_for

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
INFO = D.TargetInfo("127.0.0.1.1.1", host_name="cnc", tc_version=(3, 1, 4024), os_version=(6, 1, 0, 0, "Linux"))

#: what pyads' adsGetNetIdForPLC sends (any NetId; AMS port 10000; no tags)
PYADS_IDENTIFY = bytes.fromhex("03661471 00000000 01000000 010101010101 1027 00000000")


def _tag(tag_id: int, data: bytes) -> bytes:
    return struct.pack("<HH", tag_id, len(data)) + data


#: an add-route request laid out as pyads' add_route_to_plc and TwinCAT engineering send it
ADD_ROUTE = (bytes.fromhex("03661471 2a000000 06000000 0a0000050101 1027 05000000")
             + _tag(12, b"bench\0") + _tag(7, bytes([10, 0, 0, 5, 1, 1])) + _tag(13, b"Administrator\0")
             + _tag(2, b"1\0") + _tag(5, b"10.0.0.5\0"))


def _allowed(ip: str) -> bool:
    return ip.startswith(("10.", "127."))


# ------------------------------------------------------------------------------------------------
# codec at known bytes
# ------------------------------------------------------------------------------------------------
def test_the_identify_request_of_pyads_decodes():
    msg = D.decode(PYADS_IDENTIFY)
    assert (msg.service, msg.net_id, msg.ams_port, msg.tags, msg.invoke_id) == (1, b"\x01" * 6, 10000, (), 0)
    assert not msg.is_response and D.encode(msg) == PYADS_IDENTIFY


def test_identify_response_bytes():
    """Header: magic, the request's invoke id, service 0x80000001, our NetId, AMS port 10000, 3 tags;
    then host name (5), OS version (4, an OSVERSIONINFO of 276 bytes), TwinCAT version (3)."""
    request = D.UdpMessage(D.SERVICE_IDENTIFY, b"\x01" * 6, invoke_id=7)
    os_info = (bytes.fromhex("14010000 06000000 01000000 00000000 00000000")
               + "Linux".encode("utf-16-le").ljust(256, b"\0"))
    expected = (bytes.fromhex("03661471 07000000 01000080 7f0000010101 1027 03000000")
                + bytes.fromhex("0500 0400") + b"cnc\0"
                + bytes.fromhex("0400 1401") + os_info
                + bytes.fromhex("0300 0400 0301b80f"))
    assert D.identify_response(request, INFO) == expected
    assert len(os_info) == D.OS_VERSION_SIZE == 276


@pytest.mark.parametrize(("status", "tail"), [(0, "00000000"), (E.ADSERR_DEVICE_INVALIDACCESS, "04070000")])
def test_add_route_response_bytes(status, tail):
    """32 bytes, as pyads reads it: service 0x80000006, NetId, port 10000, one status tag (1, 4 bytes)."""
    got = D.add_route_response(D.UdpMessage(D.SERVICE_ADD_ROUTE, bytes(6), invoke_id=0x2A), "127.0.0.1.1.1", status)
    assert got == bytes.fromhex("03661471 2a000000 06000080 7f0000010101 1027 01000000 0100 0400" + tail)
    assert len(got) == 32


def test_the_add_route_request_decodes_into_its_fields():
    msg = D.decode(ADD_ROUTE)
    assert msg.service == D.SERVICE_ADD_ROUTE and msg.invoke_id == 42 and len(msg.tags) == 5
    req = D.route_request(msg)
    assert (req.route_name, req.net_id, req.address, req.user, req.password, req.temporary) == \
        ("bench", "10.0.0.5.1.1", "10.0.0.5", "Administrator", "1", False)
    assert "password" not in repr(req) and "'1'" not in repr(req)
    assert D.route_request(D.UdpMessage(6, bytes(6), tags=((9, b"\x01\0\0\0"),))).temporary


def test_tag_values():
    assert D.tc_version_tag((3, 1, 4026)) == bytes.fromhex("0301ba0f")
    long = "é" * 300                                   # 600 bytes of UTF-8: cut at 255 bytes, never mid-character
    tag = D.string_tag(long)
    assert len(tag) == 255 and tag.endswith(b"\0") and tag[:-1].decode("utf-8") == "é" * 127
    assert D.tag_string(b"abc\0junk") == "abc" and D.tag_string(None) == "" and D.tag_string(b"\xff\0") == "\ufffd"
    major, minor, build, platform_id, text = D.host_os_version()
    assert platform_id == 0 and text and all(isinstance(n, int) and n >= 0 for n in (major, minor, build))
    assert len(D.os_version_tag(1, 2, 3, 0, "x" * 500)) == 276


@pytest.mark.parametrize(("data", "reason"), [
    (b"", "shorter than the 24-byte header"),
    (PYADS_IDENTIFY[:23], "shorter than the 24-byte header"),
    (b"\0\0\0\0" + PYADS_IDENTIFY[4:], "magic 0x00000000"),
    (PYADS_IDENTIFY[:20] + b"\x02\0\0\0" + _tag(5, b"a\0"), "2 tags announced, the datagram ends after 1"),
    (PYADS_IDENTIFY[:20] + b"\x01\0\0\0" + struct.pack("<HH", 5, 0xFFFF) + b"abc", "runs past the end"),
    (PYADS_IDENTIFY[:20] + b"\xff\xff\xff\xff", "4294967295 tags announced"),
])
def test_malformed_datagrams_are_named(data, reason):
    with pytest.raises(D.MalformedDatagram, match=reason):
        D.decode(data)


def test_bytes_after_the_announced_tags_are_ignored_and_encode_checks_tag_sizes():
    assert D.decode(PYADS_IDENTIFY + b"trailing").tags == ()
    with pytest.raises(ValueError, match="65535"):
        D.encode(D.UdpMessage(1, bytes(6), tags=((5, bytes(70000)),)))


# ------------------------------------------------------------------------------------------------
# what is answered (pure)
# ------------------------------------------------------------------------------------------------
def test_add_route_is_acknowledged_and_nothing_else_decided_by_the_request():
    reply, note, level = D.answer(ADD_ROUTE, INFO, _allowed)
    assert D.route_request(D.decode(ADD_ROUTE)).password == "1"
    msg = D.decode(reply)
    assert msg.service == 0x80000006 and msg.invoke_id == 42 and msg.tag(D.TAG_STATUS) == bytes(4)
    assert "acknowledged" in note and "password not checked" in note and level == logging.INFO
    assert "'1'" not in note                                       # the password is not logged


def test_a_route_to_an_address_outside_the_allowed_networks_is_refused_with_0x704():
    request = ADD_ROUTE.replace(b"\x05\x00\x09\x0010.0.0.5\0", _tag(5, b"192.0.2.7\0"))
    assert request != ADD_ROUTE
    reply, note, level = D.answer(request, INFO, _allowed)
    assert struct.unpack("<I", D.decode(reply).tag(D.TAG_STATUS))[0] == E.ADSERR_DEVICE_INVALIDACCESS
    assert "192.0.2.7 is outside the allowed networks" in note and level == logging.WARNING
    # a host name (not an IP address) is not resolved: the sender's address decided already
    by_name = ADD_ROUTE.replace(b"\x05\x00\x09\x0010.0.0.5\0", _tag(5, b"engpc\0"))
    assert D.decode(D.answer(by_name, INFO, _allowed).datagram).tag(D.TAG_STATUS) == bytes(4)


def test_an_add_route_without_net_id_is_answered_0x706():
    msg = D.decode(ADD_ROUTE)
    without = D.encode(D.UdpMessage(msg.service, msg.net_id, msg.ams_port,
                                    tuple(t for t in msg.tags if t[0] != D.TAG_NET_ID), msg.invoke_id))
    reply, _, _ = D.answer(without, INFO, _allowed)
    assert struct.unpack("<I", D.decode(reply).tag(D.TAG_STATUS))[0] == E.ADSERR_DEVICE_INVALIDDATA


@pytest.mark.parametrize("service", [0x80000001, 0x80000006, 0, 2, 3, 0x7FFFFFFF])
def test_responses_and_unknown_services_get_no_answer(service):
    data = D.encode(D.UdpMessage(service, bytes(6)))
    reply, note, _ = D.answer(data, INFO, _allowed)
    assert reply is None and f"0x{service:08X}" in note


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=600) | st.builds(lambda tail: PYADS_IDENTIFY[:20] + tail, st.binary(max_size=600))
       | st.builds(lambda svc, tail: ADD_ROUTE[:8] + struct.pack("<I", svc) + ADD_ROUTE[12:20] + tail,
                   st.sampled_from([1, 6]), st.binary(max_size=600)))
def test_no_datagram_makes_answer_raise(data):
    reply, note, _ = D.answer(data, INFO, _allowed)
    assert reply is None or D.decode(reply).is_response
    assert isinstance(note, str)


# ------------------------------------------------------------------------------------------------
# the responder on an AdsServer (free UDP port, raw sockets)
# ------------------------------------------------------------------------------------------------
def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _server(allowed=("127.0.0.0/8",), udp_port: int | None = None):
    srv = AdsServer({851: MemoryDevice()}, port=0, net_id="10.20.30.40.1.1", allowed=list(allowed))
    responder = D.DiscoveryResponder(D.TargetInfo("10.20.30.40.1.1", host_name="cnc"),
                                     _free_udp_port() if udp_port is None else udp_port)
    srv.attached.append(responder)
    return srv, responder


@pytest.fixture()
def udp():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.settimeout(2.0)
    yield s
    s.close()


def test_identify_and_add_route_on_the_servers_host(udp):
    srv, responder = _server()
    with srv:
        assert responder.address == ("127.0.0.1", responder.port)
        udp.sendto(PYADS_IDENTIFY[:4] + b"\x09\0\0\0" + PYADS_IDENTIFY[8:], responder.address)
        msg = D.decode(udp.recv(2048))
        assert (msg.service, msg.invoke_id, msg.net_id, msg.ams_port) == (0x80000001, 9, bytes([10, 20, 30, 40, 1, 1]),
                                                                          10000)
        assert [t for t, _ in msg.tags] == [D.TAG_HOST_NAME, D.TAG_OS_VERSION, D.TAG_TC_VERSION]
        assert D.tag_string(msg.tag(D.TAG_HOST_NAME)) == "cnc" and msg.tag(D.TAG_TC_VERSION) == b"\x03\x01\xb8\x0f"
        udp.sendto(ADD_ROUTE.replace(b"10.0.0.5\0", b"127.0.0.5\0").replace(b"\x05\x00\x09\x00", b"\x05\x00\x0a\x00"),
                   responder.address)
        assert D.decode(udp.recv(2048)).tag(D.TAG_STATUS) == bytes(4)
        assert wait_for(lambda: responder.answered == 2) and srv.allowed == [ipaddress.ip_network("127.0.0.0/8")]
    assert responder.address is None
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as again:       # stop released the port
        again.bind(("127.0.0.1", responder.port))


def test_garbage_gets_no_answer_and_stops_nothing(udp):
    rng = random.Random(14)
    garbage = [b"", b"\x03", PYADS_IDENTIFY[:23], b"\xff" * 24, PYADS_IDENTIFY[:20] + b"\xff\xff\xff\xff",
               PYADS_IDENTIFY[:20] + b"\x01\0\0\0" + struct.pack("<HH", 5, 0xFFFF) + bytes(10),
               PYADS_IDENTIFY[:8] + b"\x03\0\0\0" + PYADS_IDENTIFY[12:20] + b"\x01\0\0\0"
               + _tag(5, bytes(60000)),                                              # a huge tag
               PYADS_IDENTIFY[:8] + b"\x01\0\0\x80" + PYADS_IDENTIFY[12:],            # a response: no loop
               PYADS_IDENTIFY[:8] + b"\x03\0\0\0" + PYADS_IDENTIFY[12:],              # another service
               bytes(rng.getrandbits(8) for _ in range(65000))]
    garbage += [bytes(rng.getrandbits(8) for _ in range(rng.randrange(1, 300))) for _ in range(50)]
    srv, responder = _server()
    with srv:
        for g in garbage:
            udp.sendto(g, responder.address)
        assert wait_for(lambda: responder.ignored == len(garbage))
        udp.sendto(PYADS_IDENTIFY[:4] + b"\x63\0\0\0" + PYADS_IDENTIFY[8:], responder.address)
        assert D.decode(udp.recv(65536)).invoke_id == 0x63          # the first datagram back: no garbage answered
        # an identify with a huge tag is an identify: the answer does not grow with the request
        udp.sendto(PYADS_IDENTIFY[:20] + b"\x01\0\0\0" + _tag(5, bytes(60000)), responder.address)
        assert len(udp.recv(65536)) == len(D.identify_response(D.decode(PYADS_IDENTIFY), responder.info))
        assert wait_for(lambda: responder.answered == 2)
        with RawClient(srv.port) as c:                              # ADS over TCP still served
            r = c.call(P.request, P.CMD_READ_STATE, b"", target="10.20.30.40.1.1")
            assert r.result == 0


def test_a_client_outside_the_allowed_networks_gets_no_answer(udp, caplog):
    """As a TCP connection from there is closed at once: nothing is disclosed to it (and a forged
    sender address cannot turn the responder into an amplifier); logged once per address."""
    srv, responder = _server(allowed=["10.0.0.0/8"])
    with caplog.at_level(logging.DEBUG, logger="distctrl.ads"), srv:
        for _ in range(3):
            udp.sendto(PYADS_IDENTIFY, responder.address)
        udp.sendto(ADD_ROUTE, responder.address)
        assert wait_for(lambda: responder.refused == 4)
        udp.settimeout(0.3)
        with pytest.raises(TimeoutError):
            udp.recv(2048)
    assert responder.answered == 0
    assert [r.getMessage() for r in caplog.records if "refused" in r.getMessage()] == \
        [f"refused 127.0.0.1 (UDP {responder.port})"]


def test_a_port_that_cannot_be_bound_leaves_tcp_served_with_one_warning(caplog):
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", 0))
        srv, responder = _server(udp_port=taken.getsockname()[1])
        with caplog.at_level(logging.WARNING, logger="distctrl.ads"), srv:
            assert responder.address is None and isinstance(responder.error, OSError)
            with RawClient(srv.port) as c:
                assert c.call(P.request, P.CMD_READ_STATE, b"",
                              target="10.20.30.40.1.1").result == 0
    warnings = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(warnings) == 1 and "route discovery not answered" in warnings[0] and "TCP is served" in warnings[0]


# ------------------------------------------------------------------------------------------------
# pyads against a served machine (pyads always sends to UDP 48899)
# ------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def served():
    import pyads  # noqa: F401  (a test dependency: missing, this fails rather than skips)

    with serve_over_ads(load_scenario(SCN / "serve_z.toml"), port=0, net_id="10.20.30.40.1.1") as s:
        if s.services["ads"].discovery.address is None:
            pytest.fail(f"UDP 48899 on 127.0.0.1 cannot be bound ({s.services['ads'].discovery.error}): pyads' "
                        "adsGetNetIdForPLC and add_route_to_plc always send there; stop what holds it")
        yield s


def test_pyads_gets_the_net_id_of_the_served_machine(served):
    from pyads.pyads_ex import adsGetNetIdForPLC

    assert served.services["ads"].discovery.address == ("127.0.0.1", 48899)
    assert adsGetNetIdForPLC("127.0.0.1") == "10.20.30.40.1.1"


def test_pyads_add_route_to_plc_succeeds_and_adds_nothing(served):
    import pyads

    before = list(served.services["ads"].server.allowed)
    assert pyads.add_route_to_plc("127.0.0.1.1.2", "127.0.0.1", "127.0.0.1", "Administrator", "any password",
                                  route_name="distctrl-test") is True
    assert served.services["ads"].server.allowed == before


def test_pyads_add_route_to_an_address_outside_the_allowed_networks_is_not_added(served):
    """Status 0x704 (as TwinCAT answers refused credentials). pyads 3.6 looks for the status one byte
    off and raises RuntimeError for it instead of returning False; either way it is no success."""
    import pyads

    try:
        result = pyads.add_route_to_plc("192.0.2.7.1.1", "192.0.2.7", "127.0.0.1", "Administrator", "1")
    except RuntimeError as exc:
        assert "\\x01\\x00\\x04\\x00\\x04\\x07\\x00\\x00" in str(exc)     # tag 1, 4 bytes, 0x704
    else:
        assert result is False


# ------------------------------------------------------------------------------------------------
# distctrl serve
# ------------------------------------------------------------------------------------------------
def test_serve_no_discovery_opens_no_udp_port(caplog):
    from distctrl.cli import main

    with caplog.at_level(logging.INFO, logger="distctrl.ads"):
        res = CliRunner().invoke(main, ["serve", str(SCN / "serve_z.toml"), "--port", "0", "--duration", "0.2",
                                        "--no-discovery"])
    assert res.exit_code == 0, res.output
    assert "ADS server" in caplog.text and "route discovery" not in caplog.text


def test_serve_answers_discovery_by_default(caplog):
    from distctrl.cli import main

    with caplog.at_level(logging.INFO, logger="distctrl.ads"):
        res = CliRunner().invoke(main, ["serve", str(SCN / "serve_z.toml"), "--port", "0", "--duration", "0.2"])
    assert res.exit_code == 0, res.output
    lines = [r.getMessage() for r in caplog.records if "route discovery" in r.getMessage()]
    # on 127.0.0.1:48899, or (if another program holds that port) the one warning
    assert lines == ["ADS route discovery on UDP 127.0.0.1:48899"] or \
        (len(lines) == 1 and lines[0].startswith("ADS route discovery not answered: UDP 127.0.0.1:48899"))
