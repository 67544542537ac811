"""The closed-loop batch kernel does not replay a scenario's [[process]] functions (PLC programs that
command distance control, docs/process.md): such a scenario is refused with ClosedLoopError, not run
with a recorder in place of the controller (which crashed with an AttributeError)."""
from pathlib import Path

import pytest

from distctrl.batch.closed_loop import ClosedLoopError, prepare

EX = Path(__file__).resolve().parents[2] / "examples" / "scenarios"


@pytest.mark.parametrize("name", ["process_touch.toml", "process_collision.toml"])
def test_a_scenario_with_process_functions_is_refused(name):
    with pytest.raises(ClosedLoopError) as exc:
        prepare(EX / name)
    assert "[[process]]" in str(exc.value)
