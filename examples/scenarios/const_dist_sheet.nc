%CONST_DIST_SHEET
; laser head 1 mm above a wavy sheet with a thickness step and the 2.8 mm obstacle
N10 G90 G0 X0 Y0 Z31
N20 Z[DIST_CTRL ON CONST_DIST SET_DIST=1]
N30 G1 X400 F6000
N40 Z[DIST_CTRL OFF]
N50 G0 Z40
N60 M30
