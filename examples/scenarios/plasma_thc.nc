%PLASMA_THC
; plasma torch height control: 1.5 mm cutting height from the arc voltage (the PLC linearises
; V.E.ARC_VOLTAGE into V.E.SENSOR), over a wavy sheet and across an earlier cut (a 2 mm kerf at X = 200)
N10 G90 G0 X0 Z31.5
N20 Z[DIST_CTRL SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]
N30 Z[DIST_CTRL ON CONST_DIST SET_DIST=1.5]
N40 G1 X300 F3000
N50 Z[DIST_CTRL OFF]
N60 G0 Z40
N70 M30
