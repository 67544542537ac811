"""The data layout of the closed-loop batch kernels (:mod:`distctrl.batch.closed_loop`,
:mod:`distctrl.batch.soa`): the columns of a packed parameter set (``Q_*``, after the law's filter
coefficients), of the scenario's plant vector (``PL_*``) and the njit helpers that read the plant
vector, and the error IDs the kernels report.

Both kernels read it; neither imports the other for it (``closed_loop.run_batch`` calls ``soa``).
"""
from __future__ import annotations

from numba import njit

from ..control import law
from ..errors import ErrorId
from . import kernel as _kernel  # the law-constant columns (P_*)

# ----------------------------------------------------------------------------- layouts

# per parameter set: the float64 vector ``prm`` (after the law's fc in a packed row)
# the first columns are the law's constants, in the layout of distctrl.batch.kernel (put_law_constants)
Q_T, Q_KP, Q_I_GAIN, Q_D_GAIN, Q_V_MAX, Q_A_BASE, Q_W_V, Q_W_A, Q_A_FLOOR = (
    _kernel.P_T, _kernel.P_KP, _kernel.P_I_GAIN, _kernel.P_D_GAIN, _kernel.P_V_LIM, _kernel.P_A_BASE,
    _kernel.P_W_V, _kernel.P_W_A, _kernel.P_A_FLOOR)
Q_ADAPTIVE, Q_A_MIN, Q_DEV_A_MIN, Q_DEV_A_MAX, Q_OPTIMIZED, Q_BOTH = range(9, 15)
Q_MAX_DEV, Q_CHECK_SW, Q_SW_MIN, Q_SW_MAX = range(15, 19)
Q_JUMP, Q_S_HI, Q_S_LO = range(19, 22)
Q_MM_PER_INCR, Q_SIGN_REV, Q_REF_OFF, Q_MODULO, Q_MIN_POS, Q_MAX_POS = range(22, 28)
Q_PROBE_IPM, Q_PROBE_REF = range(28, 30)
Q_LEN = 30
#: a packed row: ``[fc (law.FC_LEN) | prm (Q_LEN)]``
PACKED_LEN = law.FC_LEN + Q_LEN

# the scenario's plant and select (``plant``)
PL_Z0, PL_ACT0, PL_KV, PL_VMAX, PL_DV, PL_BUS, PL_RES, PL_FF = range(8)
PL_RMIN, PL_RMAX, PL_DELAY, PL_NOISE, PL_K_ON, PL_MODE, PL_SET = range(8, 15)
# the drive's mechanical resonance: 1.0 when resonant, then Phi = expm(A T) (physics.resonance_step)
PL_RESONANT, PL_P11, PL_P12, PL_P21, PL_P22 = range(15, 20)
# the sensor: SENSOR_PROBE (encoder 2, increments) or SENSOR_DISTANCE (the point distance sensor, a V.E.
# variable in mm: range [0, range max] = PL_RMIN, PL_RMAX, the resolution PL_DRES, PL_NCHAR points of
# its characteristic after the vector: plant[PL_LEN:PL_LEN + n] true mm, plant[PL_LEN + n:PL_LEN + 2n]
# reported mm); PL_K_FIRST: the cycle with no earlier reading (0; the distance sensor: the cycle the
# control switches to SENSOR_SOURCE=VARIABLE, whose reading it takes at once)
PL_SENSOR, PL_K_FIRST, PL_DRES, PL_NCHAR = range(20, 24)
PL_LEN = 24
SENSOR_PROBE, SENSOR_DISTANCE = 0, 1

MODE_SET_POS, MODE_CONST_DIST = 0, 1
_E_JUMP = int(ErrorId.SENSOR_JUMP)
_E_RUN_MAX = int(ErrorId.SENSOR_RUN_OUT_MAX)
_E_RUN_MIN = int(ErrorId.SENSOR_RUN_OUT_MIN)
_E_MAX_DEV = int(ErrorId.MAX_DEVIATION)
_E_SW = int(ErrorId.SW_LIMIT)
_LAND = 1e-9                    # as controller._LAND


# ----------------------------------------------------------------------------- reading the plant vector

@njit(nogil=True, error_model="numpy", inline="always")
def plant_constants(plant):
    """What every set shares, from the ``PL_*`` vector: (kv, drive v_max, drive a_max*T, bus delay
    cycles, encoder resolution, feed-forward, probe range min, max, probe dead time cycles, noise on,
    select cycle, CONST_DIST, set value)."""
    return (plant[PL_KV], plant[PL_VMAX], plant[PL_DV], int(plant[PL_BUS]), plant[PL_RES], plant[PL_FF],
            plant[PL_RMIN], plant[PL_RMAX], int(plant[PL_DELAY]), plant[PL_NOISE] != 0.0, int(plant[PL_K_ON]),
            int(plant[PL_MODE]) == MODE_CONST_DIST, plant[PL_SET])


@njit(nogil=True, error_model="numpy", inline="always")
def sensor_constants(plant):
    """The sensor from the ``PL_*`` vector: (distance sensor?, the cycle with no earlier reading,
    the distance sensor's resolution, its characteristic's true and reported values (views of the
    plant vector's tail; empty without one))."""
    nchar = int(plant[PL_NCHAR])
    return (int(plant[PL_SENSOR]) == SENSOR_DISTANCE, int(plant[PL_K_FIRST]), plant[PL_DRES],
            plant[PL_LEN:PL_LEN + nchar], plant[PL_LEN + nchar:PL_LEN + 2 * nchar])


@njit(nogil=True, error_model="numpy", inline="always")
def resonance_constants(plant):
    """The drive's resonance from the ``PL_*`` vector: (resonant, p11, p12, p21, p22)."""
    return plant[PL_RESONANT] != 0.0, plant[PL_P11], plant[PL_P12], plant[PL_P21], plant[PL_P22]
