"""TaskKinematics: the [J | drift] reduction through a weld against a direct evaluation of its formula."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from humanoid_sim.controllers.thesis.command import TASK_FRAMES
from humanoid_sim.controllers.thesis.taskspace import LWA, TaskKinematics, skew
from humanoid_sim.robot.model import HumanoidModel, load_model


@pytest.fixture(scope="module")
def hm() -> HumanoidModel:
    return load_model()


def _direct(hm: HumanoidModel, q: np.ndarray, v: np.ndarray, point: str, body: str,
            weld: str) -> tuple[np.ndarray, np.ndarray]:
    """J_red and drift of taskspace's module docstring, from freshly read pinocchio frame quantities."""
    model = hm.model
    data = model.createData()
    pin.forwardKinematics(model, data, q, v, np.zeros(model.nv))
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    fp, fb, fw = (hm.frame_id(n) for n in (point, body, weld))
    J = {f: pin.getFrameJacobian(model, data, f, LWA) for f in (fp, fb, fw)}
    a0 = {f: pin.getFrameClassicalAcceleration(model, data, f, LWA).vector for f in (fp, fb, fw)}
    S = skew(data.oMf[fw].translation - data.oMf[fp].translation)
    cols, sign = hm.theta_v_idx, hm.theta_sign
    Jr = np.vstack([J[fp][:3] - J[fw][:3] - S @ J[fw][3:], J[fb][3:] - J[fw][3:]])[:, cols] * sign
    dr = np.concatenate([a0[fp][:3] - a0[fw][:3] - S @ a0[fw][3:], a0[fb][3:] - a0[fw][3:]])
    return Jr, dr


@pytest.mark.parametrize("point, body, weld", [
    ("Pc_17", "O_17", "O_3"),   # point and body on one joint (the angular rows shared)
    ("P_tpL", "O_2", "O_3"),
    ("O_2", "O_2", "O_4"),
    ("Pc_17", "O_2", "O_3"),    # on different joints: the body's angular rows replace the point's
])
def test_reduce_pair_matches_the_formula(hm: HumanoidModel, point: str, body: str, weld: str) -> None:
    rng = np.random.default_rng(7)
    q = pin.randomConfiguration(hm.model, -np.ones(hm.model.nq), np.ones(hm.model.nq))
    v = rng.normal(size=hm.model.nv)
    kin = TaskKinematics(hm, TASK_FRAMES)
    kin.update(q, v)
    J, drift = kin.reduce_pair(point, body, weld)
    J_ref, drift_ref = _direct(hm, q, v, point, body, weld)
    np.testing.assert_allclose(J, J_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(drift, drift_ref, rtol=0, atol=1e-12)
    # cached until the next update, and the frame state agrees with the reduced quantities' sources
    assert kin.reduce_pair(point, body, weld)[0] is J
    st = kin.state(point)
    np.testing.assert_array_equal(st.p, kin.placement(point)[0])
    np.testing.assert_array_equal(st.v, kin.velocity(point))
