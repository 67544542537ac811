"""PLC process function: linearise a plasma torch's arc voltage into the distance variable.

Distance control reads its sensor signal from a V.E. variable (``SENSOR_SOURCE=VARIABLE
SENSOR_VAR=V.E.SENSOR``, PROG #DIST CTRL; FCT-M3 §12.8.4 "Example configuration of sensor
variables"). FCT-M3 §12.3 "CNC and PLC tasks" gives the PLC the job of supplying the *idealised*
sensor value: "The PLC must remove non-linear dependencies from the sensor value" and supplies the
distance itself. A plasma torch has no distance sensor: the arc voltage grows with the arc length,
``V = V0 + k·d`` (V0 the cathode and anode falls, k the column gradient in V/mm). This PLC program
inverts it every cycle::

    (* PLC task at the GEO cycle: arc voltage (V) -> distance (mm) *)
    V.E.SENSOR := (V.E.ARC_VOLTAGE - V0) / K;

with ``V0`` and ``K`` its parameters, set by the integrator from a calibration (torch at known
heights). A wrong calibration shows as a wrong distance, as on the machine: a ``V0`` off by ΔV
holds the torch ΔV/k too high or too low. A NaN voltage (no arc, a broken input) gives a NaN
distance, which the control reports as an invalid sensor value.

A PLC program on the virtual machine is a callable ``program(machine, cycle)`` that runs at the
start of every GEO cycle, before the CNC consumes the control units (:func:`distctrl.sim.run`'s
``plc_program``). It reads and writes the V.E. variables in ``machine.variables`` (keys with the
``V.E.`` prefix). It runs before the sensor of this cycle is read, so it linearises the voltage the
sensor delivered in the previous cycle: one cycle of dead time, as a PLC task at the GEO cycle that
reads its analog input once per task cycle. A scenario with ``[sensor] kind = "arc_voltage"`` runs
this program by itself (``sensor.plc_v0``, ``sensor.plc_k``; docs/scenarios.md), before any
``plc_program`` given to the run.
"""
from __future__ import annotations

import math

from ..errors.config import require_number
from .variables import ve_name

__all__ = ["ArcVoltageLinearisation", "ARC_V0_RANGE", "ARC_K_RANGE"]

#: allowed V0 (V) and k (V/mm) of the linearisation and of the simulated arc (scenario keys)
ARC_V0_RANGE = (0.0, 400.0)
ARC_K_RANGE = (0.5, 50.0)



class ArcVoltageLinearisation:
    """``distance_variable := (voltage_variable - v0) / k`` every cycle (module docstring).

    ``v0`` in V, ``k`` in V/mm; variable names with or without the ``V.E.`` prefix.
    :func:`distctrl.plc.chain.chain` runs it with further PLC programs in one task.
    """

    def __init__(self, v0: float, k: float, voltage_variable: str = "V.E.ARC_VOLTAGE",
                 distance_variable: str = "V.E.SENSOR"):
        name = "ArcVoltageLinearisation"
        self.v0 = require_number(v0, f"{name}.v0", lo=ARC_V0_RANGE[0], hi=ARC_V0_RANGE[1])
        self.k = require_number(k, f"{name}.k", lo=ARC_K_RANGE[0], hi=ARC_K_RANGE[1])
        self.voltage_variable = ve_name(voltage_variable)
        self.distance_variable = ve_name(distance_variable)
        self._inv_k = 1.0 / self.k

    def distance(self, voltage: float) -> float:
        """The distance (mm) this linearisation gives for ``voltage`` (V)."""
        return (voltage - self.v0) * self._inv_k

    def __call__(self, machine, cycle: int) -> None:
        variables = machine.variables
        v = variables.get(self.voltage_variable, math.nan)
        variables[self.distance_variable] = (v - self.v0) * self._inv_k

    def __repr__(self) -> str:
        return (f"ArcVoltageLinearisation(v0={self.v0!r}, k={self.k!r}, "
                f"voltage_variable={self.voltage_variable!r}, distance_variable={self.distance_variable!r})")
