%DIST_2
;Select + set expected position of the workpiece surface
N10 Z[DIST_CTRL ON SET_POS=30]
N20 G1 X100 F3000
N30 Z[DIST_CTRL FREEZE]      ;Hold position
N40 G0 Z60                   ;Lift with the offset frozen
N50 G0 X0
N60 Z[DIST_CTRL OFF]         ;Deselect
N999 M30
