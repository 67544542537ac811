"""Write issue 16's two plates: examples/scenarios/plasma_plate.{toml,nc} and laser_sheet.{toml,nc}.

    python tools/make_plates.py            # (re)writes the four files; they are committed

The layouts (docs/process.md, "The two plates"):

* **plasma plate** 600 x 400 mm, 5 m/min, arc voltage with the slow-down model: five 560 x 50 mm
  parts (4 x 90° corners each, 20 in all), their long edges across six earlier cuts (1.5 mm kerfs
  along Y at X = 90 ... 540: 6 x 2 x 5 = 60 kerf crossings) and past 40 earlier-cut Ø 10 mm holes
  (8 a part, 4 on each long edge), each crossed through its centre; warped 4 mm (a dome: the middle
  4 mm above the rim).
* **laser sheet** 500 x 300 mm, 20 m/min, capacitive sensor (Ø 6 mm electrode): the sheet ends at
  X = 500 mm (the edge); four 100 x 60 mm parts across 16 Ø 10 mm holes (through their centres),
  four cuts that run into the edge, one trim cut along the edge 2 mm inside it; 0.5 mm
  waviness (peak to peak) along X and Y.

The program: rapid to the first start, down to 2 mm above the plate's highest point, 0.15 s in position
(the drive's lag), the touch-off (``V.E.TOUCH_OFF = V.E.IHS``, ``#WAIT FOR V.E.TOUCH_OFF == 0``: with
the scenario variable IHS = 1 the touch_off function probes down and backs off to the pierce height;
the runs without the functions set IHS = 0 and the select comes down instead), distance control
selected once (WAIT), then the cuts with a G0 at the cut height from each cut's end to the
next start: the ``lift`` function lifts the head over these rapids ("frog jump"); without it they run
at the cut height with distance control on. OFF and up at the end. ``--short`` writes the shortened variants the tests
run (plasma_plate_short.*, laser_sheet_short.*: the first part, the same features under it).
"""
from __future__ import annotations

import argparse
from pathlib import Path

OUT = Path(__file__).resolve().parents[1] / "examples" / "scenarios"

# --- plasma plate --------------------------------------------------------------------------------
P_BASE = 30.0            # mm: the plate's mean top surface
P_WARP = 2.0             # mm amplitude: the dome's middle 2 mm above, its rim 2 mm below the mean
P_SIZE = (600.0, 400.0)
P_KERFS = [90.0 * i for i in range(1, 7)]          # X of the earlier cuts along Y (6)
P_KERF_W = 1.5
P_PARTS = [(20.0, 30.0 + 75.0 * i, 580.0, 80.0 + 75.0 * i) for i in range(5)]   # (x0, y0, x1, y1)
P_HOLE_X = [45.0, 225.0, 315.0, 495.0]             # 4 holes on each long edge, between the kerfs
HOLE_D = 10.0
P_FEED = 5000.0          # mm/min
P_SET = 1.5              # mm: the cut height (SET_DIST)
P_SAFE = 45.0            # Z at the start and the end: 13 mm above the dome's top
P_APPROACH = 34.0        # Z the touch-off starts from: 2 mm above the dome's top (30 + 2)


#: "with the functions": the [[process]] tables of each plate, all with their documented defaults
#: (benchmarks and tests run the plates with them and without them: processes = ())
PROCESS_PLASMA = """
# the cutting-process functions (docs/process.md), their defaults: touch off at the first start (probe
# at 10 mm/s, back off to 3 mm), hold the height at the corners
# (path below 90 % of F) and while the arc voltage changes faster than 500 V/s (kerfs, holes); lift the head
# 5 mm over the rapids between the cuts while X/Y move
[[process]]
function = "touch_off"
axis = "Z"

[[process]]
function = "corner_lock"
axis = "Z"

[[process]]
function = "void_lock"
axis = "Z"

[[process]]
function = "lift"
axis = "Z"
"""
PROCESS_LASER = """
# the cutting-process functions (docs/process.md), their defaults: touch off at the first start (probe
# at 10 mm/s, back off to 3 mm), hold the height at the corners
# (path below 90 % of F) and while the distance changes faster than 80 mm/s (holes, the edge); lift the head
# 5 mm over the rapids between the cuts while X/Y move
[[process]]
function = "touch_off"
axis = "Z"

[[process]]
function = "corner_lock"
axis = "Z"

[[process]]
function = "void_lock"
axis = "Z"

[[process]]
function = "lift"
axis = "Z"
"""


def plasma_holes(parts):
    holes = []
    for x0, y0, x1, y1 in parts:
        for x in P_HOLE_X:
            holes.append((x, y0))                    # on the lower edge
            holes.append((x, y1))                    # on the upper edge
    return holes


def program_nc(lines, cuts, feed, set_dist, safe, approach):
    """The cuts (polylines [(x, y), ...]) as one program: down to ``approach`` at the first start, the
    touch-off (when the scenario variable IHS is 1), distance control selected once, G1 along each cut, a G0 at the cut height from one cut's end to
    the next cut's start (the lift function lifts the head over it), OFF and up at the end."""
    n = 20

    def add(text):
        nonlocal n
        n += 10
        lines.append(f"N{n} {text}")
    x0, y0 = cuts[0][0]
    add(f"G0 X{x0:g} Y{y0:g}")
    add(f"G0 Z{approach:g}                         ; above the highest point of the plate")
    add("#TIME 0.15                          ; in position: the Z drive's lag settles")
    add("V.E.TOUCH_OFF = V.E.IHS             ; initial height sense when IHS = 1 (the PLC's touch_off)")
    add("#WAIT FOR V.E.TOUCH_OFF == 0        ; done: FREEZE at the pierce height")
    add(f"Z[DIST_CTRL WAIT ON CONST_DIST SET_DIST={set_dist:g}]")
    for k, cut in enumerate(cuts):
        if k:
            add(f"G0 X{cut[0][0]:g} Y{cut[0][1]:g}")
        first = True
        for (xa, ya), (xb, yb) in zip(cut, cut[1:]):
            words = (f"X{xb:g} " if xb != xa else "") + (f"Y{yb:g}" if yb != ya else "")
            add(f"G1 {words.strip()}" + (f" F{feed:g}" if first else ""))
            first = False
    add("Z[DIST_CTRL OFF]")
    add(f"G0 Z{safe:g}")
    add("M30")
    lines.append("")


def rectangle(x0, y0, x1, y1):
    """A rectangular part, counter-clockwise from (x0, y0) back to it."""
    return [(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)]


def plasma(short: bool) -> tuple[str, str]:
    parts = P_PARTS[:1] if short else P_PARTS
    holes = plasma_holes(parts)
    name = "plasma_plate_short" if short else "plasma_plate"
    crossings = 2 * len(P_KERFS) * len(parts)
    lines = [f"%{name.upper()}",
             f"; {len(parts)} parts at {P_FEED / 1000:g} m/min: {4 * len(parts)} x 90° corners, {crossings} kerf crossings,",
             f"; {len(holes)} holes crossed; generated by tools/make_plates.py",
             f"N10 G90 G0 Z{P_SAFE:g}",
             "N20 Z[DIST_CTRL SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]"]
    program_nc(lines, [rectangle(*part) for part in parts], P_FEED, P_SET, P_SAFE, P_APPROACH)
    hole_list = ",\n    ".join(", ".join(f"[{x:g}, {y:g}]" for x, y in holes[i:i + 6]) for i in range(0, len(holes), 6))
    kerfs = "\n".join(f'  {{ type = "step", axis = "X", at = {x:g}, height = -40.0, width = {P_KERF_W:g} }},'
                      for x in P_KERFS)
    DURATION = 30.0 if short else 150.0
    toml = f'''# generated by tools/make_plates.py ({"--short" if short else "the full plate"}); docs/process.md, "The two plates"
name = "{'plasma plate, shortened (the first part)' if short else 'plasma plate'}: {len(holes)} holes, {crossings} kerf crossings, 90° corners, 4 mm warp, 5 m/min"
cycle_time = 0.001
program = "{name}.nc"
duration = {DURATION}                         # s: an upper bound (the program ends well before)
# the machine's initial height sense: 1 = the program asks the touch_off function for it (V.E.TOUCH_OFF);
# the runs without the functions set it 0 (distctrl.sim.plates): distance control's select comes down
variables = {{ IHS = 1 }}

[axes.X]
v_max = 500.0
a_max = 1000.0

[axes.Y]
v_max = 500.0
a_max = 1000.0

[axes.Z]
params = "z_plasma_plate.lis"
start = {P_SAFE:g}
kv = 40.0
v_max = 200.0
a_max = 5000.0

[surface]
base = {P_BASE:g}
features = [
  # the 4 mm warp: a dome, the middle {P_WARP:g} mm above and the rim {P_WARP:g} mm below the mean surface
  {{ type = "sine", axis = "X", amplitude = {P_WARP / 2:g}, wavelength = {P_SIZE[0]:g}, phase = -1.5707963267948966 }},
  {{ type = "sine", axis = "Y", amplitude = {P_WARP / 2:g}, wavelength = {P_SIZE[1]:g}, phase = -1.5707963267948966 }},
  # six earlier cuts along Y: 1.5 mm kerfs through the plate
{kerfs}
  # earlier-cut Ø {HOLE_D:g} mm holes through the plate, crossed through their centres
  {{ type = "holes", diameter = {HOLE_D:g}, height = -40.0, centers = [
    {hole_list}] }},
]

[sensor]
axis = "Z"
kind = "arc_voltage"
variable = "SENSOR"
voltage_variable = "ARC_VOLTAGE"
arc_v0 = 95.0
arc_k = 6.0
arc_ripple = 2.0
arc_noise_std = 0.3
kerf_jump = 30.0                        # V with no sheet under the whole arc root (kerfs, holes)
footprint_radius = 1.0                  # mm: where the arc root may attach
range_max = 4.5                         # mm: the arc voltage stops rising beyond (over a hole: 95 + 27 + 30 V,
                                        # linearised 9.5 mm, inside the axis's 10 mm sensor window)
# the arc voltage rises as the torch slows below the cut speed (corners): 10 V at rest
arc_speed_volts = 10.0
arc_cut_speed = {P_FEED / 60:.4g}                  # mm/s: 5 m/min
seed = 16
{PROCESS_PLASMA}'''
    return toml, "\n".join(lines)


# --- laser sheet ---------------------------------------------------------------------------------
L_BASE = 30.0
L_WAVE = 0.15            # mm amplitude of the waviness along X (with 0.10 along Y: 0.5 mm peak to peak)
L_EDGE = 500.0           # X where the sheet ends
L_PARTS = [(40.0 + 110.0 * i, 40.0, 140.0 + 110.0 * i, 100.0) for i in range(4)]
L_HOLE_X = [65.0, 115.0]                            # per part, relative to x0 - 40 ... (see laser_holes)
L_FEED = 20000.0
L_SET = 1.0
L_SAFE = 42.0            # Z at the start and the end: 11.75 mm above the sheet's highest point
L_APPROACH = 33.0        # Z the touch-off starts from: 2.75 mm above the sheet's highest point
L_EDGE_CUTS = [(420.0, 150.0 + 30.0 * i, L_EDGE, 150.0 + 30.0 * i) for i in range(4)]   # into the edge
L_TRIM = (L_EDGE - 2.0, 130.0, L_EDGE - 2.0, 280.0)                                    # along the edge


L_WAVE_Y = (0.10, 150.0, 1.0)                       # amplitude, wavelength, phase of the Y waviness


def laser_holes(parts):
    holes = []
    for x0, y0, x1, y1 in parts:
        for dx in (25.0, 75.0):
            holes.append((x0 + dx, y0))
            holes.append((x0 + dx, y1))
    return holes


def laser(short: bool) -> tuple[str, str]:
    parts = L_PARTS[:1] if short else L_PARTS
    edge_cuts = L_EDGE_CUTS[:1] if short else L_EDGE_CUTS
    holes = laser_holes(parts)
    name = "laser_sheet_short" if short else "laser_sheet"
    lines = [f"%{name.upper()}",
             f"; {len(parts)} parts, {len(edge_cuts)} cuts into the sheet's edge and a trim cut along it at "
             f"{L_FEED / 1000:g} m/min;",
             f"; {len(holes)} holes crossed; generated by tools/make_plates.py",
             f"N10 G90 G0 Z{L_SAFE:g}",
             "N20 Z[DIST_CTRL SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]"]
    cuts = [rectangle(*part) for part in parts] + [[(xa, ya), (xb, yb)] for xa, ya, xb, yb in edge_cuts + [L_TRIM]]
    program_nc(lines, cuts, L_FEED, L_SET, L_SAFE, L_APPROACH)
    hole_list = ",\n    ".join(", ".join(f"[{x:g}, {y:g}]" for x, y in holes[i:i + 6]) for i in range(0, len(holes), 6))
    DURATION = 15.0 if short else 40.0
    toml = f'''# generated by tools/make_plates.py ({"--short" if short else "the full sheet"}); docs/process.md, "The two plates"
name = "{'laser sheet, shortened' if short else 'laser sheet'}: an edge, {len(holes)} holes, 0.5 mm waviness, 20 m/min"
cycle_time = 0.001
program = "{name}.nc"
duration = {DURATION}                         # s: an upper bound (the program ends well before)
# the machine's initial height sense: 1 = the program asks the touch_off function for it (V.E.TOUCH_OFF);
# the runs without the functions set it 0 (distctrl.sim.plates): distance control's select comes down
variables = {{ IHS = 1 }}

[axes.X]
v_max = 500.0
a_max = 5000.0

[axes.Y]
v_max = 500.0
a_max = 5000.0

[axes.Z]
params = "z_laser_sheet.lis"
start = {L_SAFE:g}
kv = 60.0
v_max = 300.0
a_max = 20000.0

[surface]
base = {L_BASE:g}
features = [
  # 0.5 mm waviness (peak to peak): 0.15 mm amplitude along X, 0.10 mm along Y
  {{ type = "sine", axis = "X", amplitude = {L_WAVE:g}, wavelength = 200.0 }},
  {{ type = "sine", axis = "Y", amplitude = {L_WAVE_Y[0]:g}, wavelength = {L_WAVE_Y[1]:g}, phase = {L_WAVE_Y[2]:g} }},
  # the sheet ends at X = {L_EDGE:g} mm: beyond it the support grid is 40 mm lower, out of the sensor's reach
  {{ type = "step", axis = "X", at = {L_EDGE:g}, height = -40.0 }},
  # earlier-cut Ø {HOLE_D:g} mm holes through the plate, crossed through their centres
  {{ type = "holes", diameter = {HOLE_D:g}, height = -40.0, centers = [
    {hole_list}] }},
]

[sensor]
axis = "Z"
kind = "distance"                       # capacitive sensor writing V.E.SENSOR
variable = "SENSOR"
range_max = 9.0                         # mm: over a hole it reads this, inside the axis's 10 mm sensor window
footprint_radius = 3.0                  # mm: the nozzle's electrode
noise_std = 0.002
delay_cycles = 1
seed = 16
# plume/spark bursts: on average 2 a second, 20 ms each, 0.05 mm std, reading 0.05 mm too close
bursts = {{ rate = 2.0, duration = 0.02, amplitude = 0.05, offset = -0.05 }}
{PROCESS_LASER}'''
    return toml, "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args()
    for short in (False, True):
        for make, stem in ((plasma, "plasma_plate"), (laser, "laser_sheet")):
            toml, nc = make(short)
            stem = stem + ("_short" if short else "")
            (args.out / f"{stem}.toml").write_text(toml, encoding="utf-8")
            (args.out / f"{stem}.nc").write_text(nc, encoding="utf-8")
            print(f"wrote {args.out / stem}.toml, .nc")


if __name__ == "__main__":
    main()
