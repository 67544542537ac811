%CALIBRATE_CAPACITIVE
; calibration run of a capacitive sensor (distctrl calibrate): the head is put 5 mm above a flat
; sheet, the sensor selected, and the program waits while the PLC's calibrate function drives the
; head down to 0.3 mm and back (twice), recording the reading against the axis position
N10 G90 G0 Z35
N20 Z[DIST_CTRL SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]
N30 #TIME 30
N40 M30
