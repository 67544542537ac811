; FCT-M3 §12.4.2.1 "Example: Inclination of tool via CA kinematic" (kinematic 98 with HD1 10 mm,
; HD2 50°, HD3 70°, HD4 91°, tool length 80 mm; the head inclines to A=90° with the TCP kept),
; copied as printed (N210 three times, no M30); only these comment lines were added.
;DistCtrl-OnOff.nc
; 80 mm tool length
N100 V.G.WZ_AKT.L = 80

; HD1 geometric tool head offset
N200 V.G.KIN_STEP[1].ID[98].PARAM[0] = 100000
; inclination angle starting at which tool head is maintained constant
N210 V.G.KIN_STEP[1].ID[98].PARAM[1] = 500000
; max. inclination angle up to which the distance is maintained
; constant
N210 V.G.KIN_STEP[1].ID[98].PARAM[2] = 700000
; max. inclination angle starting at which an error is output
N210 V.G.KIN_STEP[1].ID[98].PARAM[3] = 910000

N220 #TRAFO [ 9, 98]
N240 G01 A90 F10
