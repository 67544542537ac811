%DIST_4
;Set distance parameters
N10 Z[DIST_CTRL SET_POS=30]
;Select specifying the position of the workpiece surface (SET_POS)
N20 Z[DIST_CTRL ON]
N30 G1 X100 F3000
N40 Z[DIST_CTRL OFF]         ;Deselect
N50 G1 X0 Y50 F3000
;Select specifying the workpiece surface (SET_DIST)
N60 Z[DIST_CTRL SET_DIST=10]
N70 Z[DIST_CTRL ON CONST_DIST]
N80 G1 X100 F3000
N90 Z[DIST_CTRL OFF]           ;Deselect
N999 M30
