component distctrl_qtplasmac "distctrl_thc in a QtPlasmaC configuration: its enable, the Z offset sum and QtPlasmaC's THC LEDs";
description """
The glue between plasmac, QtPlasmaC's GUI and distctrl_thc (docs/linuxcnc.md, `distctrl linuxcnc config`),
one component so that the configuration loads no module another HAL file loads (it does not depend on
TWOPASS). Each period, before distctrl-thc.0:

* thc-enable-out (to distctrl-thc.0.thc-enable): on while QtPlasmaC's THC switch (thc-enable-in, the
  plasmac:thc-enable signal) is on, plasmac cuts (state = cut-state, plasmac's CUT_MODE_01, 11), the
  torch is on, the arc is OK and the path is not held (feed-hold), for thc-delay s in a row (plasmac's
  THC delay, plasmac:thc-delay) and the material's cut height is at least min-cut-height; off in the
  same period any of them falls. So torch off (M5) and plasmac
  leaving its cut state end the control before the arc voltage drops: no 70329 at the end of a cut.
* z-offset-counts-out (to axis.z.eoffset-counts): plasmac's counts plus distctrl_thc's (the same scale).
* z-command (to distctrl-thc.0.axis-z-command): Z as commanded (axis.z.pos-cmd) plus plasmac's offset.
* QtPlasmaC's LEDs (the previous period's distctrl_thc outputs): led-enabled (the THC switch), led-active
  (distctrl_thc ACTIVE/ACTIVE_CONST_DIST), led-up / led-down (its offset's velocity), led-error (ERROR).
""";
pin in bit thc_enable_in "QtPlasmaC's THC switch (the plasmac:thc-enable signal)";
pin in s32 plasmac_state "plasmac.state-out";
pin in s32 cut_state = 11 "plasmac's CUT_MODE_01 state (plasmac 1.235)";
pin in bit torch_on "plasmac.torch-on";
pin in bit arc_ok "plasmac.arc-ok-out";
pin in bit feed_hold "plasmac.feed-hold";
pin in float thc_delay = 0.5 "plasmac:thc-delay (s)";
pin in float cut_height "the material's cut height (plasmac:cut-height, mm), distctrl_thc's set-dist";
pin in float min_cut_height = 0.2 "no enable while the cut height is below this (mm)";
pin out bit thc_enable_out "to distctrl-thc.0.thc-enable";
pin in s32 plasmac_counts "plasmac.z-offset-counts";
pin in s32 own_counts "distctrl-thc.0.z-offset-counts";
pin out s32 z_offset_counts_out "to axis.z.eoffset-counts";
pin in float z_pos_cmd "axis.z.pos-cmd (without external offsets)";
pin in float offset_scale "plasmac.offset-scale (mm per count)";
pin out float z_command "to distctrl-thc.0.axis-z-command";
pin in s32 dthc_state "distctrl-thc.0.state";
pin in float dthc_velocity "distctrl-thc.0.velocity";
pin out bit led_enabled "to qtplasmac.led_thc_enabled";
pin out bit led_active "to qtplasmac.led_thc_active";
pin out bit led_up "to qtplasmac.led_thc_up";
pin out bit led_down "to qtplasmac.led_thc_down";
pin out bit led_error "distctrl_thc in ERROR";
variable double on_time;
function _ fp;
license "GPL";
author "distctrl";
;;
FUNCTION(_) {
    int cutting = thc_enable_in && plasmac_state == cut_state && torch_on && arc_ok && !feed_hold
                  && cut_height >= min_cut_height;
    on_time = cutting ? on_time + fperiod : 0.0;
    thc_enable_out = cutting && on_time >= thc_delay;
    z_offset_counts_out = plasmac_counts + own_counts;
    z_command = z_pos_cmd + plasmac_counts * offset_scale;
    led_enabled = thc_enable_in;
    led_active = dthc_state == 1 || dthc_state == 4;
    led_up = led_active && dthc_velocity > 1e-6;
    led_down = led_active && dthc_velocity < -1e-6;
    led_error = dthc_state == 5;
}
