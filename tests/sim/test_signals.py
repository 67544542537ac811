"""The trace-signal catalogue (distctrl/sim/signals.py): one entry per signal, read by the column list
and the row builder alike, so that a new signal is one line and the two cannot drift apart."""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest

from distctrl.control import CycleOutput
from distctrl.sim import signals
from distctrl.sim.machine import Machine
from distctrl.sim.runner import load_program
from distctrl.sim.scenario import load_scenario

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
#: an axis variant with a probe, a 3D channel with the CA head, a resonant drive
LAYOUTS = ("const_dist_sheet", "app_90", "resonant_z")


def machine(name: str) -> Machine:
    sc = load_scenario(SCN / f"{name}.toml")
    return Machine(sc, load_program(sc))


def test_every_signal_has_a_unique_name_a_unit_and_a_reader():
    for group in (signals.AXIS_SIGNALS + (signals.NOZZLE_SIGNAL,), signals.DC_SIGNALS, signals.TRUE_SIGNALS,
                  signals.DC3D_SIGNALS):
        names = [name for name, _, _ in group]
        assert len(names) == len(set(names))
        assert all(unit and expr for _, unit, expr in group)
    assert signals.DC_COLUMNS == tuple(name for name, _, _ in signals.DC_SIGNALS)
    assert list(signals.DC3D_COLUMNS) == [name for name, _, _ in signals.DC3D_SIGNALS]


def test_the_dc_signals_and_the_recordable_values_are_fields_of_the_cycle_output():
    fields = {f.name for f in dataclasses.fields(CycleOutput)} | set(dir(CycleOutput))
    assert {attr for _, _, attr in signals.DC_SIGNALS} <= fields
    assert set(signals.RECORDABLE) <= fields


@pytest.mark.parametrize("name", LAYOUTS)
def test_row_and_columns_line_up_for_every_layout(name):
    m = machine(name)
    record = ("kp", "a_max_int")
    cols, units = signals.trace_columns(m, record)
    assert cols[:2] == ["t", "line"] and set(units) == set(cols) and len(cols) == len(set(cols))
    for _ in range(20):
        m.step()
    row = signals.row_builder(m, record)(0.02, 7)
    assert len(row) == len(cols)
    values = dict(zip(cols, row))
    assert values["t"] == 0.02 and values["line"] == 7
    assert values["true.distance"] == m.true_distance
    for ax in m.dc_axes:
        assert values[f"{ax}.dc.offset"] == m.outputs[ax].offset
        assert values[f"{ax}.dc.kp"] == float(m.outputs[ax].kp)
        assert units[f"{ax}.dc.state"] == "-" and units[f"{ax}.dc.offset"] == "mm"
    for ax in m.axis_names:
        assert values[f"{ax}.act"] == m.drives[ax].actual
        assert units[f"{ax}.act"] == ("deg" if ax in "ABC" else "mm")
        assert (f"{ax}.nozzle" in cols) == bool(m.drives[ax].resonance_hz)
    if m.ch3d is not None:
        assert values["dc3d.offset"] == m.out3d.core.offset and units["dc3d.inclination"] == "deg"
        assert math.isfinite(values["true.distance_orth"])
    else:
        assert not any(c.startswith(("dc3d.", "tcp.")) for c in cols)


def test_the_scope_default_and_the_3d_plot_name_existing_columns():
    cols_3d, _ = signals.trace_columns(machine("app_90"))
    assert set(signals.PLOT_3D) <= set(cols_3d)
    cols, _ = signals.trace_columns(machine("const_dist_sheet"))
    assert {s.format(ax="Z") for s in signals.SCOPE_DEFAULT} <= set(cols)


def test_a_new_signal_is_one_entry(monkeypatch):
    """One line in the catalogue gives its column, its unit and its value."""
    monkeypatch.setattr(signals, "TRUE_SIGNALS", signals.TRUE_SIGNALS + (("true.xy_x", "mm", "m.true_xy[0]"),))
    m = machine("const_dist_sheet")
    cols, units = signals.trace_columns(m)
    for _ in range(5):
        m.step()
    row = signals.row_builder(m)(0.0, 1)
    assert cols[-1] == "true.xy_x" and units["true.xy_x"] == "mm" and row[-1] == m.true_xy[0]


def test_old_import_places_still_work():
    from distctrl.sim import runner
    assert runner.trace_columns is signals.trace_columns and runner.row_builder is signals.row_builder
    assert runner.RECORDABLE is signals.RECORDABLE and runner.PLOT_3D is signals.PLOT_3D
