"""Geometry of the channel-specific 3D distance control (FCT-M3 ch. 12, PROG #DIST CTRL, SPEC §11).

Pure functions and small frozen dataclasses; mm and rad internally, degrees and 1e-4 units only at
the edges (:meth:`Kinematic98Params.from_raw`, :func:`cs_rotation`). See docs/kinematics.md.

* :mod:`.ca_head`      CA head: tool direction, inverse angles, RTCP pivot <-> TCP.
* :mod:`.kin98`        kinematic 98: parameters, virtual tool length, maximum inclination (900020).
* :mod:`.geometry`     inclination, planes and height fields, orthogonal / along-ray distances.
* :mod:`.compensation` compensation direction per MODE (ACS/MCS/PCS/ECS/OFF), orthogonal effect.
* :mod:`.frames`       #CS rotation (Z-Y'-X'', P-CHAN-00394 default) and frames.
"""
from .ca_head import SINGULAR_TOL, CaAxes, CaHeadRtcp, ca_angles_from_direction, ca_tool_direction
from .compensation import CompensationMode, compensation_direction, compensation_vector, orthogonal_change
from .frames import (DEFAULT_ROTATION_SEQUENCE, ROTATION_SEQUENCES, Frame, check_rotation,
                     cs_angles_from_rotation, cs_rotation, rot_x, rot_y, rot_z)
from .geometry import (PARALLEL_TOL, HeightField, Plane, angle_between, clamping_point,
                       clamping_point_distance, distance_along, inclination, orthogonal_distance,
                       surface_normal, unit)
from .kin98 import (KIN98_MAX_INCLINATION_EXCEEDED, KIN98_PARAM_KEYS, InclinationViolation,
                    Kinematic98Params, orthogonal_set_distance)

__all__ = [
    "ca_tool_direction", "ca_angles_from_direction", "CaHeadRtcp", "CaAxes", "SINGULAR_TOL",
    "CompensationMode", "compensation_direction", "compensation_vector", "orthogonal_change",
    "cs_rotation", "cs_angles_from_rotation", "rot_x", "rot_y", "rot_z", "check_rotation", "Frame",
    "ROTATION_SEQUENCES", "DEFAULT_ROTATION_SEQUENCE",
    "unit", "inclination", "angle_between", "orthogonal_distance", "distance_along", "surface_normal",
    "Plane", "HeightField", "clamping_point", "clamping_point_distance", "PARALLEL_TOL",
    "Kinematic98Params", "InclinationViolation", "KIN98_MAX_INCLINATION_EXCEEDED", "KIN98_PARAM_KEYS",
    "orthogonal_set_distance",
]
