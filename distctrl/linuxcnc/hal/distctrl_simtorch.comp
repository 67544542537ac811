component distctrl_simtorch "A height-dependent simulated plasma torch for LinuxCNC's simulator (distctrl linuxcnc config)";
description """
Debian's sim-torch gives the same voltage at any torch height, so no THC can close a loop on it. This
torch gives the arc voltage from the torch's height over a plate (docs/linuxcnc.md "The sim torch"):
height h = z - surface(x), the surface surface-z + slope * x + warp * sin(2 pi x / warp-period) (mm);
while the arc burns, voltage = v0 + k * h + noise, the noise uniform in +-noise V (a fixed xorshift
sequence from seed: runs repeat). Over the hole (hole-x0 <= x <= hole-x1, hole-width 0: none) the arc
reaches the metal beside it: the voltage is hole-volts higher. The arc lights on torch-on when the torch
is within max-height of the metal and not touching it, and goes out when torch-on falls, when h leaves
0 .. max-height (arc loss; lit again only by the next torch-on) or while arc-loss is set (a fault to
inject). float-switch is on once the torch is float-travel below the surface (the floating head's
switch after its travel, as plasmac's float-switch-travel expects); contact is on at h <= 0.
""";
pin in bit torch_on "plasmac.torch-on";
pin in float x "the torch's X (mm), e.g. plasmac's axis-x-position";
pin in float z "the torch's Z (mm) with every offset: the Z joint's feedback (joint.N.pos-fb)";
pin in bit arc_loss "1: the arc goes out (fault injection); it lights again at the next torch-on";
pin in float surface_z = -140.0 "the plate's top at x = 0 (mm)";
pin in float slope "the plate's rise per mm of X";
pin in float warp "the warp's amplitude (mm)";
pin in float warp_period = 300.0 "the warp's period along X (mm)";
pin in float hole_x0 "the hole's start (mm of X)";
pin in float hole_width "the hole's width along X (mm; 0: no hole)";
pin in float hole_volts = 30.0 "the arc voltage's rise over the hole (V)";
pin in float v0 = 95.0 "arc voltage at zero height (V)";
pin in float k = 6.0 "arc voltage per mm of height (V/mm)";
pin in float noise = 0.5 "noise amplitude (V, uniform)";
pin in u32 seed = 12345 "the noise's seed";
pin in float max_height = 10.0 "the arc does not light or goes out above this height (mm)";
pin in float float_travel = 1.5 "the float switch trips this far below the surface (mm)";
pin out float voltage "the arc voltage (V), to plasmac.arc-voltage-in";
pin out bit arc_ok "the arc burns";
pin out bit float_switch "the floating head's switch";
pin out bit contact "the torch touches the plate (h <= 0)";
pin out float height "the torch's height over the plate (mm)";
pin out float surface "the plate's top under the torch (mm)";
function _ fp;
variable unsigned rng;
variable int was_on;
license "GPL";
author "distctrl";
;;
#include <rtapi_math.h>

FUNCTION(_) {
    double s = surface_z + slope * x + (warp_period > 0.0 ? warp * sin(2.0 * M_PI * x / warp_period) : 0.0);
    double h = z - s;
    double u;
    if (rng == 0) rng = seed ? seed : 1u;
    rng ^= rng << 13; rng ^= rng >> 17; rng ^= rng << 5;          /* xorshift32 */
    u = (double)rng / 4294967295.0 * 2.0 - 1.0;
    surface = s;
    height = h;
    contact = h <= 0.0;
    float_switch = h <= -float_travel;
    if (!torch_on || arc_loss || h <= 0.0 || h > max_height) arc_ok = 0;   /* out until the next torch-on */
    else if (!was_on) arc_ok = 1;                                         /* lights at torch-on */
    was_on = torch_on;
    if (arc_ok) {
        double hole = (hole_width > 0.0 && x >= hole_x0 && x <= hole_x0 + hole_width) ? hole_volts : 0.0;
        voltage = v0 + k * h + hole + noise * u;
    } else {
        voltage = 0.0;
    }
}
