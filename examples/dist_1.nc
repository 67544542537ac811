%DIST_1
;Set expected position of the workpiece surface
N10 Z[DIST_CTRL SET_POS=30]
N20 Z[DIST_CTRL ON]           ;Select
N30 G1 X100 Y50 F3000
N40 Z[DIST_CTRL OFF]         ;Deselect
N999 M30
