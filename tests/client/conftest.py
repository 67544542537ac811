"""Served machines for the ADS client tests: ``distctrl serve``'s ServedMachine on a loopback address
of its own (pyads' AdsLib always connects to TCP 48898, so each test server takes a free
127.x.y.z:48898 instead of a free port)."""
from __future__ import annotations

import random
import signal
import socket

import pytest

pyads = pytest.importorskip("pyads")


def pytest_configure(config):
    config.addinivalue_line("markers", "loop: the whole commissioning loop against distctrl serve (a minute or "
                                       "two of CPU; -m 'not loop' leaves it out)")


@pytest.fixture(autouse=True)
def _own_write_journal(tmp_path, monkeypatch):
    """Every test its own journal of machine writes (distctrl.client.journal), never the user's."""
    monkeypatch.setenv("DISTCTRL_MACHINE_JOURNAL", str(tmp_path / "machine-writes.json"))


def _sigint_default() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


#: Popen keywords for a child that a test stops with SIGINT (Ctrl-C): the child gets SIGINT's default
#: disposition, as from a terminal; a test run started as a background job of a non-interactive shell
#: (``make test &``) ignores SIGINT, and a child would inherit that and never see the signal
CTRL_C_ABLE = {"preexec_fn": _sigint_default}


def free_loopback(port: int = 48898) -> str:
    """A 127.x.y.z address whose ``port`` can be bound (other tests and engineers use others)."""
    rng = random.Random()
    for _ in range(200):
        host = f"127.{rng.randint(1, 254)}.{rng.randint(0, 254)}.{rng.randint(1, 254)}"
        with socket.socket() as s:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                s.bind((host, port))
            except OSError:
                continue
        return host
    pytest.skip(f"no free loopback address for TCP {port}")


def serve_on_port(scenario, speed: float = 1.0, port: int = 0):
    """A started ServedMachine of ``scenario`` on 127.0.0.1 and a free AMS/TCP port (``sm.port``), or
    ``port``, as ``distctrl serve --port N`` serves it; its NetId is 127.0.0.1.1.1."""
    from distctrl.ads.devices import serve_over_ads

    sm = serve_over_ads(scenario, host="127.0.0.1", port=port, net_id="127.0.0.1.1.1", discovery_port=None,
                        speed=speed)
    sm.start()
    sm.server = sm.services["ads"].server
    sm.net_id, sm.host, sm.port = "127.0.0.1.1.1", "127.0.0.1", sm.server.port
    return sm


def closed_port() -> int:
    """A TCP port on 127.0.0.1 with nothing listening (bound, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def serve(scenario, speed: float = 1.0):
    """A started ServedMachine of ``scenario`` on a free loopback address; its NetId is the address + .1.1."""
    from distctrl.ads.devices import serve_over_ads

    host = free_loopback()
    sm = serve_over_ads(scenario, host=host, port=48898, net_id=f"{host}.1.1", discovery_port=None, speed=speed)
    sm.start()
    sm.net_id, sm.host, sm.server = f"{host}.1.1", host, sm.services["ads"].server
    return sm
