%TUNE_SHEET
; laser head selected 1.5 mm above a wavy sheet (SET_DIST 1 mm: a 0.5 mm approach), then a 0.5 mm thickness step
N10 G90 G0 X0 Y0 Z31.5
N20 Z[DIST_CTRL ON CONST_DIST SET_DIST=1]
N30 G1 X300 F9000
N40 Z[DIST_CTRL OFF]
N50 G0 Z40
N60 M30
