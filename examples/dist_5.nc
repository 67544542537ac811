%DIST_5
;Select filter type
N10Z[DIST_CTRL FILTER_TYPE=KALMAN_MA]
;Parametrise filter
N20 Z[DIST_CTRL N_CYCLES=30 KALMAN_SIGMA=1000]
;DRYRUN needs a set value (SPEC 12: the document's example omits it)
N25 Z[DIST_CTRL SET_POS=30]
;Check the filter effect on the sensor signal
N30 Z[DIST_CTRL DRYRUN]
N40 G1 X100 F3000
;Parameterise the PID controller
N50 Z[DIST_CTRL KP=0.3 I_TN=0 D_TV=0.01]
;Activate distance control
N60 Z[DIST_CTRL ON CONST_DIST SET_DIST=1]
N70 G1 X200 F3000
;Change filter
N80 Z[DIST_CTRL FILTER_TYPE=KALMAN_EXPO SMOOTH_FACT=0.3]
N90 G1 X300 F3000
N100 Z[DIST_CTRL OFF];           Deselect
N999 M30
