#!/usr/bin/python3
"""Drive a running LinuxCNC QtPlasmaC configuration headless (distctrl/linuxcnc/sim.py runs it with
Debian's python3, whose ``linuxcnc`` and ``hal`` modules it needs; it imports nothing of distctrl).

argv[1]: JSON {"program", "samples" (a TSV to write), "pins" [...], "max_seconds", "actions" [{"x": mm,
"setp": [pin, value]}: set a pin once the torch passes X (a fault to inject)]}. It releases the sim's
E-stop, switches the machine on, homes, enables the torch, opens and runs the program, samples the
pins every ~10 ms (until the program ends, or pause_grace s after it paused) and prints one JSON line:
{"completed", "started", "paused", "errors", "messages", "samples", "seconds"}.
"""
import json
import subprocess
import sys
import time

import hal
import linuxcnc

spec = json.loads(sys.argv[1])
s, c, e = linuxcnc.stat(), linuxcnc.command(), linuxcnc.error_channel()
errors, messages = [], []


def halcmd(*args):
    return subprocess.run(["halcmd", *args], capture_output=True, text=True)


def poll():
    s.poll()
    while True:
        m = e.poll()
        if not m:
            break
        kind, text = m
        (errors if kind in (linuxcnc.OPERATOR_ERROR, linuxcnc.NML_ERROR) else messages).append(text)


def wait(cond, seconds):
    t = time.time()
    while time.time() - t < seconds:
        poll()
        if cond():
            return True
        time.sleep(0.05)
    return False


time.sleep(3)                                                     # the GUI's own startup settles
if halcmd("getp", "estop_or.in0").returncode == 0:               # the sim panel's E-stop
    halcmd("setp", "estop_or.in0", "0")
time.sleep(0.5)
c.state(linuxcnc.STATE_ESTOP_RESET)
c.wait_complete()
c.state(linuxcnc.STATE_ON)
c.wait_complete()
wait(lambda: s.task_state == linuxcnc.STATE_ON, 20)
c.mode(linuxcnc.MODE_MANUAL)
c.wait_complete()
c.teleop_enable(0)
c.wait_complete()
c.home(-1)
c.wait_complete()
wait(lambda: all(s.homed[i] for i in range(s.joints)), 90)
# the operator's TORCH ENABLE button (its HAL input does not toggle it headless)
halcmd("unlinkp", "plasmac.torch-enable")
halcmd("setp", "plasmac.torch-enable", "1")
c.teleop_enable(1)
c.wait_complete()
time.sleep(1)
c.mode(linuxcnc.MODE_AUTO)
c.wait_complete()
c.program_open(spec["program"])
c.wait_complete()
time.sleep(1)
probe = hal.component("distctrl-sim-drive")      # hal.get_value needs a component of this process
probe.ready()
pins = spec["pins"]
actions = list(spec.get("actions", []))
started = completed = False
attempts, last_try, paused_at = 0, 0.0, 0.0
t0 = time.time()
n = 0
with open(spec["samples"], "w") as f:
    f.write("\t".join(["t", "interp", "line", "x", "y", "z"] + pins) + "\n")
    while time.time() - t0 < spec["max_seconds"]:
        poll()
        if not started and s.interp_state != linuxcnc.INTERP_IDLE and s.current_line > 0:
            started = True                    # a line of the program runs (a run can end before its first)
        if not started:
            if attempts >= 5:
                break
            if s.interp_state == linuxcnc.INTERP_IDLE and time.time() - last_try > 3.0:
                # QtPlasmaC switches back to MANUAL after a program is opened: AUTO again, run again
                if s.task_mode != linuxcnc.MODE_AUTO:
                    c.mode(linuxcnc.MODE_AUTO)
                    c.wait_complete()
                c.auto(linuxcnc.AUTO_RUN, 0)
                attempts, last_try = attempts + 1, time.time()
            time.sleep(0.01)
            continue
        x = s.position[0]
        for a in [a for a in actions if x >= a["x"]]:
            halcmd("setp", *[str(v) for v in a["setp"]])
            actions.remove(a)
        vals = []
        for p in pins:
            try:
                vals.append(str(hal.get_value(p)))
            except Exception:
                vals.append("nan")
        f.write("\t".join([f"{time.time() - t0:.3f}", str(s.interp_state), str(s.current_line), f"{x:.4f}",
                           f"{s.position[1]:.4f}", f"{s.actual_position[2]:.4f}"] + vals) + "\n")
        n += 1
        if s.interp_state == linuxcnc.INTERP_IDLE and s.exec_state == linuxcnc.EXEC_DONE:
            completed = not s.paused
            break
        if s.paused:
            paused_at = paused_at or time.time()
            if time.time() - paused_at > spec.get("pause_grace", 8.0):   # paused (plasmac): seen, done
                break
        else:
            paused_at = 0.0
        time.sleep(0.01)
time.sleep(1)
poll()
print(json.dumps({"completed": completed, "started": started, "paused": bool(s.paused), "errors": errors, "messages": messages,
                  "samples": n, "seconds": round(time.time() - t0, 2)}))
