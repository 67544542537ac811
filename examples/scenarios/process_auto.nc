%PROCESS_AUTO
; plasma cut at 5 m/min over a flat plate; the set distance is sampled at the cut height
N05 G90 G0 X0 Z31.5
N10 Z[DIST_CTRL SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]
N20 Z[DIST_CTRL ON CONST_DIST SET_DIST=1.0]   ; a placeholder: the automatic set value replaces it
N30 G1 X200 F5000
N40 Z[DIST_CTRL OFF]
N50 M30
