"""MuJoCo as an engine: state in Pinocchio's convention, torques held over a control period (zero-order hold).

::

    sim = MujocoSim(hm)                     # or MujocoSim(hm, MujocoSettings.from_scenario(scenario))
    sim.set_state(q, v)                     # Pinocchio q (nq = 33, quaternion xyzw), v (base twist LOCAL)
    sim.step(tau, 0.01)                     # tau (nv,) generalized forces in Pinocchio v order, held 10 ms
    q, v = sim.state()
    wrenches = sim.foot_wrenches()          # {'R': FootContact, 'L': FootContact}, world frame

``step`` writes the joint rows of tau to the 26 motors (the base rows are ignored: nothing actuates the base)
and advances ``round(h / timestep)`` MuJoCo steps with them unchanged.  MuJoCo resolves impacts and contact
switching inside its steps; there is no velocity reset.  ``step`` is ``hold(tau)`` then ``advance(n)``: a caller
that reads the state between the MuJoCo steps of one control period holds once and advances twice.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import mujoco
import numpy as np

from humanoid_sim.engines.mujoco import compiled as mjc
from humanoid_sim.engines.mujoco.contact import FootContact, foot_contacts
from humanoid_sim.engines.mujoco.disturb import TerrainBox
from humanoid_sim.engines.mujoco.model import MujocoModel, MujocoSettings, build_model
from humanoid_sim.engines.mujoco.state import StateMap
from humanoid_sim.errors import SimulationError
from humanoid_sim.robot.model import HumanoidModel

_BAD = (mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQPOS,
        mujoco.mjtWarning.mjWARN_BADCTRL)
_BAD_ROWS = np.array([int(w) for w in _BAD], dtype=np.intp)
"""Their rows of ``data.warning``, in _BAD's order."""
_VEL_STAGE = int(mujoco.mjtStage.mjSTAGE_VEL)
_EULER, _RK4 = int(mujoco.mjtIntegrator.mjINT_EULER), int(mujoco.mjtIntegrator.mjINT_RK4)


class MujocoSimError(SimulationError):
    """A MuJoCo step failed (non-finite acceleration: MuJoCo would silently reset the state) or a bad argument."""


class MujocoSim:
    """The thesis humanoid in MuJoCo, driven by joint torques (see the module docstring).

    ``compiled``: map the state and the torques with :mod:`.compiled`'s functions (None = when numba is installed,
    False = never: :class:`.state.StateMap`'s NumPy maps, the same numbers).  ``terrain``: a scenario's terrain
    boxes (:mod:`.disturb`)."""

    def __init__(self, hm: HumanoidModel, settings: MujocoSettings | None = None,
                 compiled: bool | None = None, terrain: Sequence[TerrainBox] = ()) -> None:
        self.hm = hm
        self.compiled = compiled is not False and mjc.AVAILABLE
        self.mm: MujocoModel = build_model(hm, settings, terrain)
        self.model = self.mm.model
        self.data = mujoco.MjData(self.model)
        self.map = StateMap.from_models(hm, self.model)
        self.timestep = float(self.model.opt.timestep)
        self._fresh = False
        self._warnings = self.data.warning.number  # a view: MuJoCo's warning counters, updated in place
        self._saved = (np.empty(self.model.nq), np.empty(self.model.nv))  # advance()'s copy of (qpos, qvel)
        self._qpos, self._qvel = self.data.qpos, self.data.qvel   # views: MjData's fixed-size arrays do not move
        self.set_state(hm.initial_q(), np.zeros(hm.model.nv))

    # ------------------------------------------------------------------ state
    @property
    def time(self) -> float:
        """Simulated time, s."""
        return float(self.data.time)

    @time.setter
    def time(self, t: float) -> None:
        self.data.time = float(t)

    def set_state(self, q: np.ndarray, v: np.ndarray) -> None:
        """Set the state from Pinocchio's q (nq,) and v (nv,); controls are zeroed, time unchanged."""
        self.data.qpos[:] = self.map.qpos_from_q(q)
        self.data.qvel[:] = self.map.qvel_from_v(q, v)
        self.data.ctrl[:] = 0.0
        self.data.qacc_warmstart[:] = 0.0
        mujoco.mj_forward(self.model, self.data)
        self._fresh = True

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) in Pinocchio's convention (copies)."""
        d, smap = self.data, self.map
        if self.compiled:
            return mjc.pin_state(d.qpos, d.qvel, smap.q_gather, smap.v_gather)
        qpos = d.qpos.copy()
        return smap.q_from_qpos(qpos), smap.v_from_qvel(qpos, d.qvel)

    # ------------------------------------------------------------------ stepping
    def substeps(self, h: float) -> int:
        """Number of MuJoCo steps in a control period h (s); h must be a whole number of timesteps."""
        n = round(h / self.timestep)
        if not (math.isfinite(h) and n >= 1 and abs(n * self.timestep - h) <= 1e-9 * max(1.0, h)):
            raise MujocoSimError(f"step duration h = {h!r} s: expected a positive multiple of the MuJoCo "
                                 f"timestep {self.timestep:g} s")
        return n

    def step(self, tau: np.ndarray, h: float) -> None:
        """Advance h seconds with the joint rows of ``tau`` (Pinocchio v order, N m) held on the motors.

        Raises :class:`MujocoSimError` if MuJoCo flags a non-finite or huge state, acceleration or control (it
        would otherwise reset the data or zero the control silently); the state is then restored to the start
        of the step."""
        n = self.substeps(h)
        self.hold(tau)
        self.advance(n)

    def hold(self, tau: np.ndarray) -> None:
        """Put the joint rows of ``tau`` (Pinocchio v order, N m) on the motors, for the following :meth:`advance`
        calls; raises :class:`MujocoSimError` if one is not finite."""
        if self.compiled and type(tau) is np.ndarray and tau.dtype == np.float64 and tau.shape == (self.map.nv,):
            if mjc.put_ctrl(tau, self.map.ctrl_gather, self.data.ctrl):
                return
        ctrl = self.map.ctrl_from_tau(tau)
        if not np.isfinite(ctrl).all():
            raise MujocoSimError(f"tau has non-finite joint torques at t = {self.time:.4f} s")
        self.data.ctrl[:] = ctrl

    def advance(self, n: int) -> None:
        """Advance n MuJoCo timesteps (n >= 1) with the controls held (:meth:`hold`): :meth:`step`'s checks."""
        if not (isinstance(n, int) and n >= 1):
            raise MujocoSimError(f"advance: n = {n!r} steps, expected an integer >= 1")
        m, d, warnings = self.model, self.data, self._warnings
        before = warnings.tobytes()       # all counters: only _BAD's rows matter, the others rarely change
        t_start = d.time
        qpos, qvel = self._saved
        np.copyto(qpos, self._qpos)
        np.copyto(qvel, self._qvel)
        t_end = t_start + n * self.timestep
        if self._fresh and m.opt.integrator != _RK4:
            # the position and velocity stages of this state are current (set_state, forward): mj_step without
            # computing them again, as MuJoCo's own mj_step1 / mj_step2 split does (the same numbers: those stages
            # read qpos, qvel and the model only; the controls and applied forces enter the acceleration stage).
            # RK4 evaluates its own stages: it takes the full step, as MuJoCo's split does not serve it either.
            mujoco.mj_checkPos(m, d)
            mujoco.mj_checkVel(m, d)
            mujoco.mj_forwardSkip(m, d, _VEL_STAGE, 0)
            mujoco.mj_checkAcc(m, d)
            if m.opt.integrator == _EULER:
                mujoco.mj_Euler(m, d)
            else:   # implicitfast
                mujoco.mj_implicit(m, d)
            if n > 1:
                mujoco.mj_step(m, d, n - 1)
            self._fresh = False
        else:
            mujoco.mj_step(m, d, n)
        # MuJoCo answers a non-finite or huge qpos/qvel/qacc with a warning and a reset of the data (time back to
        # 0), and a huge control with a warning and ctrl = 0: either way the run is no longer the one asked for.
        if warnings.tobytes() == before and abs(d.time - t_end) <= 1e-6 and \
                (mjc.all_finite(self._qvel) if self.compiled else np.isfinite(self._qvel).all()):
            return
        was = np.frombuffer(before, dtype=warnings.dtype)
        hit = [w.name for w, row in zip(_BAD, _BAD_ROWS) if warnings[row] != was[row]]
        if hit or abs(d.time - t_end) > 1e-6 or not np.isfinite(d.qvel).all():
            d.time, d.qpos[:], d.qvel[:] = t_start, qpos, qvel  # keep the last good state for the caller
            raise MujocoSimError(f"MuJoCo: {', '.join(hit) or 'non-finite state'} in the step from "
                                 f"t = {t_start:.4f} s (the state diverged or a torque was huge); the state is "
                                 "left at the start of the step")

    def state_before_step(self) -> tuple[np.ndarray, np.ndarray]:
        """MuJoCo's (qpos, qvel) at the start of the last :meth:`advance` (views, overwritten by the next one): the
        state whose acceleration and contact forces the data hold after an ``advance(1)``."""
        return self._saved

    def forward(self) -> None:
        """Bring MuJoCo's derived quantities (kinematics, contacts, contact forces) to the current state (the next
        :meth:`advance` reuses its position and velocity stages: after editing the model call
        :meth:`model_changed`)."""
        if not self._fresh:
            mujoco.mj_forward(self.model, self.data)
            self._fresh = True

    def model_changed(self) -> None:
        """The model's parameters were edited (e.g. ``dof_armature``): the next :meth:`forward` or :meth:`advance`
        computes every stage anew."""
        self._fresh = False

    # ------------------------------------------------------------------ outputs
    def foot_wrenches(self) -> dict[str, FootContact]:
        """Ground reaction of each foot at the current state (see :mod:`humanoid_sim.engines.mujoco.contact`)."""
        self.forward()
        return foot_contacts(self.mm, self.data)
