%PROCESS_TOUCH
; a laser head touches off over the pierce point, pierces at 3 mm and cuts at 1 mm (CONST_DIST)
N10 G90 G0 X20 Z40                      ; probe start: above the highest sheet expected
N20 Z[DIST_CTRL SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]
N30 V.E.TOUCH_OFF = 1                   ; PLC: touch off (docs/process.md)
N40 #WAIT FOR V.E.TOUCH_OFF == 0        ; done: FREEZE at the pierce height
N50 #TIME 0.3                           ; pierce
N60 Z[DIST_CTRL ON CONST_DIST SET_DIST=1]
N70 G1 X150 F6000
N80 Z[DIST_CTRL OFF]
N90 G0 Z45
N100 M30
