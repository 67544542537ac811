%CAPACITIVE_EDGE
; a laser head in CONST_DIST 1 mm cuts along the sheet's edge (X = 100 mm) with a capacitive sensor:
; the nozzle's electrode hangs partly over the edge, sees too large a distance, and the head dives
N10 G90 G0 X0 Y0 Z31
N20 Z[DIST_CTRL SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]
N30 Z[DIST_CTRL ON CONST_DIST SET_DIST=1]
N40 G1 X99.5 F6000
N50 G1 Y150 F6000
N60 G1 X50
N70 Z[DIST_CTRL OFF]
N80 G0 Z40
N90 M30
