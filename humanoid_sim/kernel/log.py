"""The per-stage log vector the compiled stages fill (numba side) and its named layout (Python side).

A stage of the thesis controller's kernel (:mod:`humanoid_sim.controllers.thesis.compiled`) or of the balance
controller's (:mod:`humanoid_sim.controllers.balance.compiled`) writes :data:`LOG_SIZE` floats that the weld engine
records instead of recomputing them (``WeldEngine._stage0_record``, its reference: the weld drifts, the dynamics
residual and the task frames' placements).  The compiled code writes at the offsets ``LOG_*`` below (numba freezes
them into the code); Python reads the same vector through :class:`StageLog`'s named fields.
"""

from __future__ import annotations

import numpy as np

from humanoid_sim.jit import njit
from humanoid_sim.kernel.kinematics import F_O1, F_O2, F_O17, F_PC17, F_TPL, F_TPR
from humanoid_sim.kernel.linalg import put, put_flat

LOG_FIELDS = (
    ("status", 1),                  # 0 ok; > 0 an actuator saturates; < 0 a normal matrix or KKT system was singular
    ("weld_position_error", 1),     # largest weld position error, m
    ("weld_orientation_error", 1),  # largest weld orientation error, rad
    ("residual", 1),                # max |M a + h - tau - Jc^T lam|, N / N m
    ("hip_p", 3),                   # Body-17 CoM (frame Pc_17) position, world, m
    ("hip_v", 3),                   # its velocity, world, m/s
    ("R_17", 9),                    # Body 17's orientation (frame O_17), row-major
    ("toe_R_p", 3),                 # right toe point P_tpR, world, m
    ("toe_L_p", 3),                 # left toe point P_tpL, world, m
    ("R_1", 9),                     # right toe body's orientation (O_1), row-major
    ("R_2", 9),                     # left toe body's orientation (O_2), row-major
    ("pad", 2),
)
"""(name, floats) of the log vector, in order."""
LOG_SLICES = {}
_o = 0
for _name, _n in LOG_FIELDS:
    LOG_SLICES[_name] = slice(_o, _o + _n)
    _o += _n
LOG_SIZE = _o
"""Floats of the log vector (45)."""
LOG_STATUS = LOG_SLICES["status"].start
LOG_POS_ERR = LOG_SLICES["weld_position_error"].start
LOG_ORI_ERR = LOG_SLICES["weld_orientation_error"].start
LOG_RESIDUAL = LOG_SLICES["residual"].start
LOG_HIP_P = LOG_SLICES["hip_p"].start
LOG_HIP_V = LOG_SLICES["hip_v"].start
LOG_R17 = LOG_SLICES["R_17"].start
LOG_TOE_R = LOG_SLICES["toe_R_p"].start
LOG_TOE_L = LOG_SLICES["toe_L_p"].start
LOG_R1 = LOG_SLICES["R_1"].start
LOG_R2 = LOG_SLICES["R_2"].start


class StageLog:
    """Named read access to a log vector (views of ``array``; scalars as NumPy floats)."""

    __slots__ = ("array",)

    def __init__(self, array: np.ndarray) -> None:
        self.array = array

    @property
    def status(self) -> float:
        """0: a regular stage; > 0: an actuator saturates; < 0: a singular normal matrix or KKT system."""
        return self.array[LOG_STATUS]

    @property
    def weld_position_error(self) -> float:
        return self.array[LOG_POS_ERR]

    @property
    def weld_orientation_error(self) -> float:
        return self.array[LOG_ORI_ERR]

    @property
    def residual(self) -> float:
        return self.array[LOG_RESIDUAL]

    @property
    def hip_p(self) -> np.ndarray:
        return self.array[LOG_SLICES["hip_p"]]

    @property
    def hip_v(self) -> np.ndarray:
        return self.array[LOG_SLICES["hip_v"]]

    @property
    def R_17(self) -> np.ndarray:
        return self.array[LOG_SLICES["R_17"]].reshape(3, 3)

    @property
    def toe_R_p(self) -> np.ndarray:
        return self.array[LOG_SLICES["toe_R_p"]]

    @property
    def toe_L_p(self) -> np.ndarray:
        return self.array[LOG_SLICES["toe_L_p"]]

    @property
    def R_1(self) -> np.ndarray:
        return self.array[LOG_SLICES["R_1"]].reshape(3, 3)

    @property
    def R_2(self) -> np.ndarray:
        return self.array[LOG_SLICES["R_2"]].reshape(3, 3)


@njit
def log_frames(log: np.ndarray, fR: np.ndarray, fpos: np.ndarray, vel: np.ndarray) -> None:
    """The task frames a stage log records (:data:`LOG_FIELDS` hip_p ... R_2): the hip CoM and its velocity, Body 17's
    orientation, both toe points, both toe bodies' orientations, from a stage's frame placements and velocities."""
    put(log, LOG_HIP_P, fpos[F_PC17])
    put(log, LOG_HIP_V, vel[F_PC17][:3])
    put_flat(log, LOG_R17, fR[F_O17])
    put(log, LOG_TOE_R, fpos[F_TPR])
    put(log, LOG_TOE_L, fpos[F_TPL])
    put_flat(log, LOG_R1, fR[F_O1])
    put_flat(log, LOG_R2, fR[F_O2])
