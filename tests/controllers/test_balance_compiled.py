"""The balance controller's compiled QP path (``controllers.balance.compiled``: ``balance_stage`` / ``balance_finish``,
the twin of ``controllers.balance.qp.qp_numpy`` and ``BalanceController._qp_reference``) against its NumPy/Pinocchio
reference (``BalanceController(compiled=False)``): at every call of real walks, on welded feet and
on MuJoCo's real ground, both give the same command."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from humanoid_sim import kernel
from humanoid_sim.controllers.balance.controller import BalanceController
from humanoid_sim.interfaces.controller import ControlContext
from humanoid_sim.kernel.log import LOG_SLICES, StageLog
from humanoid_sim.scenario.balance import BalanceSettings
from humanoid_sim.scenario.schema import load_scenario
from humanoid_sim.sim.simulate import Simulator

ROOT = Path(__file__).resolve().parents[2]
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
# numba is a required dependency: without it there is no compiled path, and that is a broken install
assert kernel.AVAILABLE, "numba is not importable"


class _Both:
    """Runs the compiled controller (its command drives the walk) and the reference on the same observations, and
    keeps the largest differences."""

    name = "balance (compiled and reference)"
    control_period_s = None   # a feedthrough, as the balance controller itself

    def __init__(self, settings: BalanceSettings | None = None) -> None:
        self.fast, self.ref = BalanceController(settings), BalanceController(settings, compiled=False)
        self.diff = {"tau": 0.0, "T": 0.0, "a": 0.0, "lam": 0.0, "box": 0.0, "log": 0.0}
        self.calls = 0
        self.kinds = set()

    def setup(self, ctx: ControlContext) -> None:
        self.fast.setup(ctx)
        self.ref.setup(ctx)
        assert self.fast._stage is not None and self.ref._stage is None

    def __call__(self, obs):
        c1, c0 = self.fast(obs), self.ref(obs)
        self.calls += 1
        self.kinds.add((obs.phase.value, obs.phase.is_double_support, bool(c1.extra["flat_trail"])))
        d = self.diff
        d["tau"] = max(d["tau"], float(np.max(np.abs(c1.tau - c0.tau))))
        d["T"] = max(d["T"], float(np.max(np.abs(c1.T_cmd - c0.T_cmd))))
        if c1.motion is not None and c0.motion is not None:
            d["a"] = max(d["a"], float(np.max(np.abs(c1.motion[0] - c0.motion[0]))))
            d["lam"] = max(d["lam"], float(np.max(np.abs(c1.motion[1] - c0.motion[1]))))
        for frame, (wm, wt) in c1.extra["box_wrenches"].items():
            rm, rt = c0.extra["box_wrenches"][frame]
            d["box"] = max(d["box"], float(np.max(np.abs(wm - rm))), float(np.max(np.abs(wt - rt))))
        lg = c1.extra.get("kernel_log")
        if lg is not None:    # the stage log the weld engine records, against Pinocchio at the same state
            model, dd = self.ref.model, self.ref.dyn.data           # the reference's prepare left it at obs
            pin.updateFramePlacements(model, dd)
            fid = self.ref.fid
            exp = np.concatenate([
                dd.oMf[fid["Pc_17"]].translation, pin.getFrameVelocity(model, dd, fid["Pc_17"], LWA).linear,
                dd.oMf[fid["O_17"]].rotation.ravel(), dd.oMf[fid["P_tpR"]].translation,
                dd.oMf[fid["P_tpL"]].translation, dd.oMf[fid["O_1"]].rotation.ravel(),
                dd.oMf[fid["O_2"]].rotation.ravel()])
            # the contacts the call used: the phase's, or with the trailing foot held flat (flat_trail)
            contacts = self.ref._trail.contacts(obs, self.ref._reference_time(obs), None).contacts \
                if c1.extra["flat_trail"] else obs.phase.contacts
            rows = self.ref.dyn.rows(contacts)
            frames = lg[LOG_SLICES["hip_p"].start:LOG_SLICES["R_2"].stop]
            r = StageLog(lg)
            d["log"] = max(d["log"], float(np.max(np.abs(frames - exp))),
                           abs(r.weld_position_error - float(np.max(rows.weld_position_error))),
                           abs(r.weld_orientation_error - float(np.max(rows.weld_orientation_error))))
            assert r.residual < 1e-6      # the base rows of the dynamics hold (the QP's equalities)
        assert c1.extra["balance_level"] == c0.extra["balance_level"]
        # the compiled finish's limit check (which skips Actuators.saturate) against the limits themselves
        assert self.fast._inside == bool(np.all(np.abs(c1.T_cmd) <= self.fast.act.limits))
        np.testing.assert_array_equal(c1.saturated, c0.saturated)
        assert self.fast._lift_k == self.ref._lift_k and self.fast._lift0 == pytest.approx(self.ref._lift0, abs=1e-12)
        return c1


@pytest.mark.slow
@pytest.mark.parametrize("engine, t_end, robot", [("pinocchio", 3.3, "thesis"), ("mujoco", 2.6, "thesis"),
                                                  ("mujoco", 2.6, "variant")])
def test_the_compiled_balance_controller_equals_the_reference(hm, variant_hm, engine, t_end, robot):
    """sim 3's zmp walk: the lead-in double support (on real ground its trailing foot held flat, then its toe-off),
    two single supports with their swings (heel return, landing depth and search on real ground) and the double
    support between them; every call compared.  Also on a robot
    variant (tests/conftest.py): nothing of the thesis robot is a constant of the compiled code."""
    hm = hm if robot == "thesis" else variant_hm
    sc = load_scenario(ROOT / "scripts" / "params" / "sim3_zmp.yaml")
    # the lead-in with its trailing foot held flat (flat_lead_in, real ground only): the QP on other contacts
    both = _Both(BalanceSettings(flat_lead_in=True))
    sim = Simulator(hm, sc, engine=engine, controller=both)
    sim.run(t_end=t_end)
    assert both.calls > 300
    assert {(p, p.endswith("DSP"), False) for p in ("LFFDSP", "LFFSSP", "RFFDSP", "RFFSSP")} <= both.kinds
    if engine == "mujoco":
        assert ("LFFDSP", True, True) in both.kinds                         # the lead-in held flat
    # The two paths sum the same products in different orders (BLAS against loops), so the QP data differ by
    # ~1e-13 relative and DAQP's optimum (multipliers ~500 N, torques ~100 N m) by more: measured 2e-11 on welds,
    # up to 1e-9 (torques, multipliers) and 2e-9 N (the heel / toe box split) on MuJoCo.  1e-8 (N m, m/s^2, N)
    # keeps a 5x margin and still catches a formula difference: a trunk gain 0.1 % off moves the torques by 1e-3
    for key, tol in (("tau", 1e-8), ("T", 1e-8), ("a", 1e-8), ("lam", 1e-8), ("box", 1e-8)):
        assert both.diff[key] <= tol, both.diff
    # placements and velocities by the kernel's forward kinematics against Pinocchio's: round-off of ~1 m values
    assert both.diff["log"] <= 1e-12, both.diff
