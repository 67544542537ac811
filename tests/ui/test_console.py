"""R18 (new-user audit): what a commissioning engineer does on the live page shows on serve's console,
one line each with the machine time: sensor faults, Reset, Feed hold, the path override, and an
object write (pending, then adopted, logged by the session log for writes from the page or ADS)."""
from __future__ import annotations

import logging
from pathlib import Path

from distctrl.ads.devices import serve_over_ads
from distctrl.sim.scenario import load_scenario
from distctrl.ui.hub import MachineHub

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "serve_z.toml"


def test_the_pages_actions_are_logged_with_the_machine_time(caplog):
    served = serve_over_ads(load_scenario(SCN), port=0, discovery_port=None)      # stepped by hand
    hub = MachineHub(served, buffer_s=1.0)
    for _ in range(10):
        served.step()
    with caplog.at_level(logging.INFO, logger="distctrl.serve"):
        assert hub.sensor_fault("jump", 30.0, None)[0]
        assert hub.sensor_fault("noise_burst", 0.5, 2.0)[0]
        assert hub.clear_faults()[0]
        assert hub.set_feed_hold(True)[0]
        assert hub.set_feed_hold(False)[0]
        assert hub.set_override(0.8)[0]
        assert hub.reset()[0]
        assert hub.write_object(2, "DIST_CTRL::kp", 0.4)[0]
        served.step()
    lines = [r.getMessage() for r in caplog.records if r.name == "distctrl.serve"]
    assert lines[:7] == ["t=0.010 s page: sensor fault jump 30 mm until cleared",
                         "t=0.010 s page: sensor fault noise_burst 0.5 mm for 2 s",
                         "t=0.010 s page: sensor faults cleared",
                         "t=0.010 s page: feed hold ON (path override 0 %)",
                         "t=0.010 s page: feed hold OFF (override 100 %)",
                         "t=0.010 s page: path override 80 %",
                         "t=0.010 s page: CNC reset: the program stops, distance control is deselected"], \
        lines
    assert any(line.startswith("t=0.011 s axis Z: DIST_CTRL::kp ") and line.endswith(
        "-> 0.4 pending (adopted on the next INACTIVE->active or FREEZE->active)") for line in lines), lines


def test_a_refused_action_of_the_page_is_not_logged_as_done(caplog):
    served = serve_over_ads(load_scenario(SCN), port=0, discovery_port=None)
    hub = MachineHub(served, buffer_s=1.0)
    with caplog.at_level(logging.INFO, logger="distctrl.serve"):
        assert not hub.sensor_fault("melt", 1.0, None)[0]
        assert not hub.write_object(2, "DIST_CTRL::kp", 7.0)[0]
        served.step()
    assert not [r for r in caplog.records if r.name == "distctrl.serve"]
