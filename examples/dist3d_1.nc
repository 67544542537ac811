; PROG #DIST CTRL "Example 1 - Behaviour as for axis-specific distance control" (3D distance control,
; FCT-M3 §12.2), copied as printed; only these comment lines were added.
N010 G0 Z10
;Set the sensor input source
N020 #DIST CTRL [SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]
;Activate distance control
N030 #DIST CTRL ON [CONST_DIST SET_DIST=1 MODE=ACS DIRECTION=Z]
;...
;Deactivate distance control with no wait Next block is executed immediately.
N900 #DIST CTRL OFF
N910 G0 Z0
N999 M30
