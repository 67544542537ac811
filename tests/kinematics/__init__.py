"""Tests of distctrl.kinematics (3D distance control geometry, FCT-M3 ch. 12, SPEC §11)."""
