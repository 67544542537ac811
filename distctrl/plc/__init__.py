"""The PLC interface (HLI) of distance control: the DistanceControl control unit and its ADS symbols
(HLI DistanceControl, FCT-M3 §8, SPEC §9). See docs/plc.md."""
from .hli import (MM_PER_UNIT, ChannelDistanceStatus, DistanceControlUnit, HliCyclicCommand,
                  HliDistanceControlCommand, HliDistanceControlState, RejectedCommand, SemaphoreBusyError,
                  transition_number)
from .symbols import (SymbolSpec, SymbolValueError, axis_unit_path, channel_status_path, channel_status_symbols,
                      cyclic_command_path, hli_symbols, process_path, process_symbols)

__all__ = ["MM_PER_UNIT", "ChannelDistanceStatus", "DistanceControlUnit", "HliCyclicCommand",
           "HliDistanceControlCommand", "HliDistanceControlState", "RejectedCommand", "SemaphoreBusyError",
           "transition_number", "SymbolSpec", "SymbolValueError", "axis_unit_path", "channel_status_path",
           "channel_status_symbols", "cyclic_command_path", "hli_symbols", "process_path", "process_symbols"]
