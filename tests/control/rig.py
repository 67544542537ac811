"""A tiny closed loop for controller tests: ideal or first-order drive, probe on encoder 2."""
from __future__ import annotations

import copy

from distctrl.control import AxisDistanceController, CycleInput, CycleOutput
from distctrl.params import AxisParameters


class Rig:
    """Axis with a probe: reading s = surface - actual (mm), delivered as increments.

    ``drive_lag`` 0: the actual position is last cycle's command position (one-cycle delay);
    otherwise a first-order lag with that time constant (s).
    """

    def __init__(self, params: AxisParameters, *, p: float = 40.0, surface: float = 40.0, T: float = 0.001,
                 drive_lag: float = 0.0, source: str = "encoder"):
        self.ctrl = AxisDistanceController(params, T)
        self.params, self.T = params, T
        self.p, self.surface, self.actual = p, surface, p
        self.drive_lag = drive_lag
        self.source = source
        self.sensor_extra = 0.0          # added to the reading (sensor fault / probe change)
        self.inp = CycleInput(programmed_position=p, actual_position=p)
        self.out = CycleOutput()
        self.history: list[CycleOutput] = []

    def reading(self) -> float:
        return self.surface - self.actual + self.sensor_extra

    def cycle(self, *commands, n: int = 1, **inputs) -> CycleOutput:
        for k in range(n):
            inp = self.inp
            inp.programmed_position = self.p
            inp.actual_position = self.actual
            s = self.reading()
            inp.sensor_increments = s / self.params.sensor_mm_per_increment * (-1 if self.params.sensor_sign_reversal else 1)
            inp.sensor_variable = -s
            for key, value in inputs.items():
                setattr(inp, key, value)
            if k == 0:
                inp.commands.extend(commands)
            self.result = self.ctrl.update(inp, self.out)
            self.history.append(copy.copy(self.out))
            c = self.out.command_position
            if self.out.absorbed_offset:
                self.p += self.out.absorbed_offset        # the channel takes the offset over
            if self.drive_lag <= 0:
                self.actual = c
            else:
                self.actual += (c - self.actual) * (self.T / self.drive_lag)
        return self.history[-1]

    def run_until(self, predicate, limit: int = 20000, **inputs) -> CycleOutput:
        for _ in range(limit):
            out = self.cycle(**inputs)
            if predicate(out):
                return out
        raise AssertionError("condition not reached")

    def events(self):
        return [ev for o in self.history for ev in o.events]

    def event_ids(self):
        return [ev.id for ev in self.events()]
