"""Tests of distctrl.kinematics (3D distance control geometry, seeds/000 ch. 12, SPEC §11)."""
