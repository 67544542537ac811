"""ADS (Beckhoff Automation Device Specification) server over AMS/TCP.

Makes the virtual CNC reachable by standard ADS clients (pyads, TwinCAT, Beckhoff AdsLib).
See docs/ads.md. Typical use::

    from distctrl.ads import AdsServer
    server = AdsServer({551: cnc_objects, 851: plc}, lock=sim_lock)
    server.start()
    ...
    server.stop()
"""
from __future__ import annotations

from .errors import AdsError
from .protocol import ADS_TCP_PORT, IEC_TYPES, AdsDevice, SymbolInfo
from .server import AdsServer

__all__ = ["ADS_TCP_PORT", "IEC_TYPES", "AdsDevice", "AdsError", "AdsServer", "SymbolInfo"]
