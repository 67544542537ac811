%DIST_3
;Select + set expected position of the workpiece surface
N10 Z[DIST_CTRL ON SET_POS=50]
N20 G1 X100 F3000
;Deactivate distance control; Z axis does not move
N30 Z[DIST_CTRL OFF NO_MOVE]
;The generated compensation offset is included for motion
;to the target point 100
N40 G0 Z100
N999 M30
