; FCT-M3 §12.9 application example 2: monitoring minimum height in the range [0°; -]
; The height of the tool head is kept constant from the start of the inclination: HD2 = 0°.
; "-" (no end angle) cannot reach 90° (the extension L/cos θ would be infinite): HD3 = 80°,
; above it the extension stops (SPEC §11) and the height falls with cos θ.
; The tool (L = 80 mm, HD1 = 100 mm) is inclined stepwise from 0° to 90° with the TCP kept on
; the nominal surface z = 0; 3D distance control (SET_DIST = tool length, MODE=MCS) compensates
; the real sheet's height offset orthogonally to the surface (frozen for the last step). docs/run-3d.md
V.G.KIN_STEP[1].ID[98].PARAM[0] = 1000000     ; HD1 100 mm
V.G.KIN_STEP[1].ID[98].PARAM[1] = 0     ; HD2 0°
V.G.KIN_STEP[1].ID[98].PARAM[2] = 800000     ; HD3 80°
V.G.KIN_STEP[1].ID[98].PARAM[3] = 910000      ; HD4 91°
V.G.WZ_AKT.L = 80
#KIN ID[9.98]
#TRAFO ON
#DIST CTRL [SENSOR_SOURCE=VARIABLE SENSOR_VAR=V.E.SENSOR]
#DIST CTRL WAIT ON [CONST_DIST SET_DIST=V.G.WZ_AKT.L MODE=MCS DIRECTION=Z]
#TIME 0.5
G1 A10 F600
#TIME 1
G1 A20 F600
#TIME 1
G1 A30 F600
#TIME 1
G1 A40 F600
#TIME 1
G1 A50 F600
#TIME 1
G1 A60 F180
#TIME 1
G1 A70 F180
#TIME 1
G1 A80 F180
#TIME 1
; at 90° the clamping point reaches the sheet (height Lv·cos 90° = 0): the sensor cannot tell how
; far it would go below, so tracking is frozen for the last step and the offset kept (FREEZE)
#DIST CTRL FREEZE
G1 A90 F180
#TIME 1
#DIST CTRL WAIT OFF
M30
