"""Who may connect to a served machine: the route check that ADS (:mod:`distctrl.ads.server`) and the
live page (:mod:`distctrl.ui.app`) share (``distctrl serve --allow``, docs/serve.md)."""
from __future__ import annotations

import ipaddress
from collections.abc import Iterable

__all__ = ["address_allowed", "networks"]


def networks(allowed: Iterable[str] | str) -> list:
    """The ``ipaddress`` networks of ``--allow`` values (an address or a CIDR network, host bits allowed)."""
    items = [allowed] if isinstance(allowed, str) else list(allowed)
    return [ipaddress.ip_network(a, strict=False) for a in items]


def address_allowed(ip: str, networks) -> bool:
    """True if the peer address ``ip`` (IPv4, IPv6 with a zone, or IPv4-mapped IPv6) lies in one of
    ``networks`` (ipaddress networks): the route check of the ADS server and the live page."""
    try:
        addr = ipaddress.ip_address(ip.split("%", 1)[0])
    except ValueError:
        return False
    if addr.version == 6 and addr.ipv4_mapped is not None:
        addr = addr.ipv4_mapped
    return any(addr.version == net.version and addr in net for net in networks)
