"""ADS error codes and :class:`AdsError`.

The numeric codes are the ones of the Beckhoff ADS specification (router errors 0x0..0x1E,
device errors 0x700..), i.e. the ``err_code`` a client such as pyads reports in its
``ADSError``. Devices raise :class:`AdsError` with one of these codes; the server answers the
request with it. Any other exception escaping a device is answered with
:data:`ADSERR_DEVICE_ERROR` (0x700) and logged.
"""
from __future__ import annotations

# --- no error ---------------------------------------------------------------------------------
ERR_NOERROR = 0x0

# --- router / AMS errors (answered in the AMS header's error field) -------------------------
ERR_INTERNAL = 0x1
ERR_TARGETPORTNOTFOUND = 0x6        # target AMS port not found (no ADS server on that port)
ERR_TARGETMACHINENOTFOUND = 0x7     # target AMS NetId not found (no route to that machine)
ERR_UNKNOWNCMDID = 0x8
ERR_INVALIDAMSLENGTH = 0xE
ERR_INVALIDAMSNETID = 0xF

# --- device errors (answered in the ADS result field of the response) ------------------------
ADSERR_DEVICE_ERROR = 0x700            # general device error
ADSERR_DEVICE_SRVNOTSUPP = 0x701       # service not supported by the server
ADSERR_DEVICE_INVALIDGRP = 0x702       # invalid index group
ADSERR_DEVICE_INVALIDOFFSET = 0x703    # invalid index offset
ADSERR_DEVICE_INVALIDACCESS = 0x704    # reading/writing not permitted (e.g. write to a read-only object)
ADSERR_DEVICE_INVALIDSIZE = 0x705      # parameter size not correct
ADSERR_DEVICE_INVALIDDATA = 0x706      # invalid data value(s)
ADSERR_DEVICE_NOTREADY = 0x707         # device not in a ready state
ADSERR_DEVICE_BUSY = 0x708
ADSERR_DEVICE_INVALIDCONTEXT = 0x709
ADSERR_DEVICE_NOMEMORY = 0x70A         # out of memory (also: handle table of a connection full)
ADSERR_DEVICE_INVALIDPARM = 0x70B
ADSERR_DEVICE_NOTFOUND = 0x70C
ADSERR_DEVICE_SYNTAX = 0x70D
ADSERR_DEVICE_INCOMPATIBLE = 0x70E
ADSERR_DEVICE_EXISTS = 0x70F
ADSERR_DEVICE_SYMBOLNOTFOUND = 0x710   # symbol not found (unknown name or handle)
ADSERR_DEVICE_SYMBOLVERSIONINVAL = 0x711
ADSERR_DEVICE_INVALIDSTATE = 0x712
ADSERR_DEVICE_TRANSMODENOTSUPP = 0x713
ADSERR_DEVICE_NOTIFYHNDINVALID = 0x714
ADSERR_DEVICE_CLIENTUNKNOWN = 0x715
ADSERR_DEVICE_NOMOREHDLS = 0x716
ADSERR_DEVICE_INVALIDWATCHSIZE = 0x717
ADSERR_DEVICE_NOTINIT = 0x718
ADSERR_DEVICE_TIMEOUT = 0x719
ADSERR_DEVICE_INVALIDARRAYIDX = 0x721

#: Short descriptions (the wording follows the ADS documentation).
DESCRIPTIONS: dict[int, str] = {
    ERR_NOERROR: "no error",
    ERR_INTERNAL: "internal error",
    ERR_TARGETPORTNOTFOUND: "target port not found (ADS server not started)",
    ERR_TARGETMACHINENOTFOUND: "target machine not found (missing ADS route)",
    ERR_UNKNOWNCMDID: "unknown command ID",
    ERR_INVALIDAMSLENGTH: "invalid AMS length",
    ERR_INVALIDAMSNETID: "invalid AMS NetId",
    ADSERR_DEVICE_ERROR: "general device error",
    ADSERR_DEVICE_SRVNOTSUPP: "service is not supported by the server",
    ADSERR_DEVICE_INVALIDGRP: "invalid index group",
    ADSERR_DEVICE_INVALIDOFFSET: "invalid index offset",
    ADSERR_DEVICE_INVALIDACCESS: "reading/writing not permitted",
    ADSERR_DEVICE_INVALIDSIZE: "parameter size not correct",
    ADSERR_DEVICE_INVALIDDATA: "invalid data value(s)",
    ADSERR_DEVICE_NOTREADY: "device is not in a ready state",
    ADSERR_DEVICE_BUSY: "device is busy",
    ADSERR_DEVICE_INVALIDCONTEXT: "invalid context",
    ADSERR_DEVICE_NOMEMORY: "out of memory",
    ADSERR_DEVICE_INVALIDPARM: "invalid parameter value(s)",
    ADSERR_DEVICE_NOTFOUND: "not found",
    ADSERR_DEVICE_SYNTAX: "syntax error",
    ADSERR_DEVICE_INCOMPATIBLE: "objects do not match",
    ADSERR_DEVICE_EXISTS: "object already exists",
    ADSERR_DEVICE_SYMBOLNOTFOUND: "symbol not found",
    ADSERR_DEVICE_SYMBOLVERSIONINVAL: "symbol version invalid",
    ADSERR_DEVICE_INVALIDSTATE: "server is in an invalid state",
    ADSERR_DEVICE_TRANSMODENOTSUPP: "AdsTransMode not supported",
    ADSERR_DEVICE_NOTIFYHNDINVALID: "notification handle is invalid",
    ADSERR_DEVICE_CLIENTUNKNOWN: "notification client not registered",
    ADSERR_DEVICE_NOMOREHDLS: "no more handles",
    ADSERR_DEVICE_INVALIDWATCHSIZE: "size for watch too big",
    ADSERR_DEVICE_NOTINIT: "device not initialized",
    ADSERR_DEVICE_TIMEOUT: "device has a timeout",
    ADSERR_DEVICE_INVALIDARRAYIDX: "invalid array index",
}


def describe(code: int) -> str:
    """A short text for an ADS error code (``"unknown ADS error 0x..."`` if not catalogued)."""
    return DESCRIPTIONS.get(code, f"unknown ADS error 0x{code:X}")


class AdsError(Exception):
    """An ADS error: the server answers the request that caused it with :attr:`code`."""

    def __init__(self, code: int, message: str = "") -> None:
        self.code = int(code) & 0xFFFFFFFF
        self.message = message
        text = f"ADS error 0x{self.code:X} ({describe(self.code)})"
        super().__init__(f"{text}: {message}" if message else text)
