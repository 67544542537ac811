; PROG #DIST CTRL "Example 2 - Distance control with inclined tool and kinematic ID 98" (3D distance
; control, FCT-M3 §12.2). Kinematic-98 values as in PROG #DIST CTRL (1e-4 mm / 1e-4 degree units;
; FCT-M3 prints them a factor 10 too small, SPEC §12). Changes to the printed text, all in
; comments or PDF artefacts: the separator line ": -----" starts with ';' (a ':' is no comment),
; "SEN-SOR_VAR" is de-hyphenated to SENSOR_VAR, and the trailing "M30# distctrl ..." of the seed
; file (the next document glued on) is just M30. Only these comment lines were added.
; Parameterising the kinematic 98
; ----------------------------------
; HD1: Tool offset (100mm)
; HD2: Start limit angle (inclination to the perpendicular) Start of tool extension (30°)
; HD3: End limit angle (inclination to the perpendicular) End of tool extension (60°)
; HD4: maximum inclination -> error message (91°)
N010 V.G.KIN_STEP[1].ID[98].PARAM[0] = 1000000
N020 V.G.KIN_STEP[1].ID[98].PARAM[1] = 300000
N030 V.G.KIN_STEP[1].ID[98].PARAM[2] = 600000
N040 V.G.KIN_STEP[1].ID[98].PARAM[3] = 910000
; tool length (80mm)
N050 V.G.WZ_AKT.L = 80
; activate kinematic transformations ID9 and ID98.
N060 #KIN ID[9.98]
N070 #TRAFO ON
N080 G0 Z10
N090 G90 A=-45
; Set the sensor input source
N100 #DIST CTRL [SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]
; Activate distance control in tool direction (surface 1mm)
N110 #DIST CTRL ON [SURFACE SET_POS=1 MODE=ECS DIRECTION=Z]
;...
; Deactivate distance control and wait until the deactivation process is completed.
N120 #DIST CTRL WAIT OFF
N130 G0 Z0
N140 M30
