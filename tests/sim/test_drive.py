"""Motors between the controller and the engine: the rotor inertia in both engines' dynamics, the envelope on the
commands, the reports of a motor that cannot do the walk."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

import humanoid_sim as hs
from humanoid_sim.engines.mujoco.engine import MujocoEngine
from humanoid_sim.interfaces.controller import Command, Observation
from humanoid_sim.robot.model import THETA_NAMES, HumanoidModel
from humanoid_sim.robot.motors import load_catalogue
from humanoid_sim.scenario.actuators import parse_actuators
from humanoid_sim.scenario.schema import load_scenario
from humanoid_sim.scenario.yamlio import read_yaml
from humanoid_sim.sim.drive import Drive, with_motors

ROOT = Path(__file__).resolve().parents[2]
PARAMS = ROOT / "scripts" / "params"


def test_the_most_specific_key_chooses_each_joints_motor() -> None:
    c = parse_actuators("x.yaml", {"joints": {"all": "osl_knee", "ankle": "mini_cheetah_knee",
                                              "right_ankle": "mini_cheetah_hip", "theta7": "osl_knee", "neck": None}})
    m = {th: spec.name for th, spec in c.motors.items()}
    assert m["theta11"] == "osl_knee" and m["theta6"] == "mini_cheetah_knee"           # all; side-less group
    assert m["theta5"] == m["theta9"] == "mini_cheetah_hip" and m["theta7"] == "osl_knee"  # group; joint variable
    assert not {"theta25", "theta26", "theta27"} & set(m)                               # null: no motor
    cat = load_catalogue()
    arm = c.armature()
    assert arm[THETA_NAMES.index("theta6")] == cat["mini_cheetah_knee"].gear_ratio ** 2 * \
        cat["mini_cheetah_knee"].rotor_inertia
    assert arm[THETA_NAMES.index("theta25")] == 0.0
    off = parse_actuators("x.yaml", {"joints": {"all": "mini_cheetah_knee"}, "rotor_inertia": False})
    assert not off.armature().any() and len(off.motors) == 26


def test_a_gear_ratio_changes_the_gearbox_and_nothing_else() -> None:
    """``gear_ratio`` replaces N on the joints it names (most specific key wins, as for the motors): the joint-side
    stall torque N k_t I_max and no-load speed U / (k_t N) follow N (the DC-motor relations computed here, not by
    the motor module), the reflected inertia is N^2 J_r, every other constant is the catalogue's."""
    cat = load_catalogue()
    c = parse_actuators("x.yaml", {"joints": {"all": "mini_cheetah_knee"}, "gear_ratio": {"all": 12, "hip": 30}})
    base = cat["mini_cheetah_knee"]
    hip, knee = c.motors["theta15"], c.motors["theta11"]
    assert (hip.gear_ratio, knee.gear_ratio) == (30.0, 12.0)
    assert c.gear_ratios["theta15"] == 30.0 and c.describe()["gear_ratio"]["theta11"] == 12.0
    for m, n in ((hip, 30.0), (knee, 12.0)):
        assert m.torque_constant == base.torque_constant and m.peak_current == base.peak_current
        # efficiency 1 and I_max < U / R for this motor: stall = N k_t I_max
        assert m.stall_torque == pytest.approx(n * base.torque_constant * base.peak_current, rel=1e-14)
        assert m.no_load_speed == pytest.approx(base.bus_voltage / (base.torque_constant * n), rel=1e-14)
        assert c.armature()[THETA_NAMES.index("theta15")] == pytest.approx(30.0 ** 2 * base.rotor_inertia, rel=1e-15)
    assert "gear_ratio" not in parse_actuators("x.yaml", {"joints": {"all": "osl_knee"}}).describe()


@pytest.mark.parametrize("section, words", [
    ({"joints": {"kne": "osl_knee"}}, ["actuators.joints.kne", "did you mean 'knee'"]),
    ({"joints": {"knee": "osl"}}, ["actuators.joints.knee = 'osl'", "not in the catalogue"]),
    ({"joint": {"knee": "osl_knee"}}, ["actuators.joint", "did you mean 'joints'"]),
    ({"joints": {}}, ["actuators.joints = {}", "expected a mapping"]),
    ({"catalogue": "missing.yaml", "joints": {"all": "osl_knee"}}, ["actuators.catalogue", "missing.yaml"]),
    ({"joints": {"all": "osl_knee"}, "rotor_inertia": "yes"}, ["actuators.rotor_inertia = 'yes'", "true or false"]),
    ({"joints": {"all": "osl_knee"}, "gear_ratio": {"hip": 0.5}}, ["actuators.gear_ratio.hip = 0.5", "[1, 1000]"]),
    ({"joints": {"knee": "osl_knee"}, "gear_ratio": {"hip": 50}}, ["actuators.gear_ratio: theta13 has no motor"]),
    ({"joints": {"all": "osl_knee"}, "gear_ratio": {"hips": 50}}, ["actuators.gear_ratio.hips", "did you mean 'hip'"]),
])
def test_a_bad_actuators_section_exits_2_naming_the_field(tmp_path: Path, section: dict, words: list[str]) -> None:
    import yaml

    doc = {"base": str(PARAMS / "sim3_zmp.yaml"), "actuators": section}
    (tmp_path / "bad.yaml").write_text(yaml.safe_dump(doc))
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, str(ROOT / "scripts" / "walk.py"), str(tmp_path / "bad.yaml"), "--out",
                           str(out), "--quiet"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2, proc.stderr
    for w in words:
        assert w in proc.stderr, proc.stderr
    assert not out.exists()


def test_reflected_inertia_is_the_same_torque_in_both_engines(hm: HumanoidModel) -> None:
    """One joint accelerated (2 rad/s^2) from rest, the robot in the air: the generalized torques of Pinocchio's
    RNEA on the model with the motors' armature and of MuJoCo's mj_inverse on the engine's model (its dof_armature
    set from the same model) agree to 1e-6 relative (two implementations of the same rigid-body equations; measured
    ~1e-12).  Without the armature the driven joint's torque differs by N^2 J_r times its acceleration."""
    sc = load_scenario(PARAMS / "sim3_zmp_motors.yaml")
    hm_m = with_motors(hm, sc.actuators)
    engine = MujocoEngine(hm_m, sc)
    m, d = engine.mm.model, mujoco.MjData(engine.mm.model)
    q = pin.neutral(hm_m.model)
    q[2] = 10.0                                                 # far above the ground: no contact
    worst = 0.0
    for theta in ("theta11", "theta3", "theta20"):
        i = hm_m.theta_v_idx[THETA_NAMES.index(theta)]
        a = np.zeros(hm_m.model.nv)
        a[i] = 2.0
        tau_pin = pin.rnea(hm_m.model, hm_m.model.createData(), q, np.zeros(hm_m.model.nv), a)
        d.qpos[:] = engine.map.qpos_from_q(q)
        d.qvel[:] = 0.0
        d.qacc[:] = engine.map.qfrc_from_tau(q, a)              # at rest the acceleration maps as a joint vector
        mujoco.mj_inverse(m, d)
        tau_mj = engine.map.tau_from_qfrc(q, d.qfrc_inverse)
        worst = max(worst, float(np.abs(tau_mj[6:] - tau_pin[6:]).max() / np.abs(tau_pin[6:]).max()))
        plain = pin.rnea(hm.model, hm.model.createData(), q, np.zeros(hm.model.nv), a)
        assert tau_pin[i] - plain[i] == pytest.approx(2.0 * hm_m.model.armature[i], rel=1e-9)
        assert hm_m.model.armature[i] == sc.actuators.motors[theta].reflected_inertia
    print("max relative difference", worst)
    assert worst <= 1e-6
    assert not np.any(hm.model.armature)                      # the shared model is left as it was


def test_the_drive_gives_at_most_what_the_motor_can(hm: HumanoidModel) -> None:
    """A knee asked for 80 N m at rest by a motor whose stall torque is N eta k_t min(I_max, U/R) (the datasheet
    corner, computed here from the catalogue's numbers less the drive's Coulomb friction at a small speed) gets that
    and no more, and the shortfall is recorded with its joint, time and size; a torque inside the envelope and one
    at a speed beyond the no-load speed in the braking direction pass unchanged or shrink, never reverse."""
    choice = parse_actuators("x.yaml", {"joints": {"knee": "mini_cheetah_knee"}})
    drive = Drive(with_motors(hm, choice), choice)
    spec = choice.motors["theta11"]
    q, v = pin.neutral(hm.model), np.zeros(hm.model.nv)
    i = hm.theta_v_idx[THETA_NAMES.index("theta11")]
    s = hm.theta_sign[THETA_NAMES.index("theta11")]
    v[i] = s * 1e-6                                             # just moving: friction opposes +speed
    tau = np.zeros(hm.model.nv)
    tau[i] = s * 80.0
    out = drive(Command(tau=tau.copy()), Observation(0.25, 0, None, q, v, None, 0))
    corner = spec.gear_ratio * spec.efficiency * spec.torque_constant * min(spec.peak_current,
                                                                            spec.bus_voltage / spec.resistance)
    got = s * out.tau[i]
    assert got == pytest.approx(corner - spec.coulomb_friction - spec.viscous_friction * 1e-6, rel=1e-9)
    assert out.T is None and out.motion is None                 # the engine derives them again
    sf = drive.report()["envelope_shortfalls"]
    assert sf[0]["joint"] == "theta11" and sf[0]["first_s"] == 0.25
    assert sf[0]["worst_shortfall_Nm"] == pytest.approx(80.0 - got)
    small = np.zeros(hm.model.nv)
    small[i] = s * 5.0
    same = Command(tau=small)
    assert drive(same, Observation(0.3, 0, None, q, v, None, 0)) is same
    fast = v.copy()
    fast[i] = s * 2.0 * spec.no_load_speed                     # back-driven beyond no-load: the drive gives 0
    out = drive(Command(tau=small.copy()), Observation(0.35, 0, None, q, fast, None, 0))
    assert 0.0 <= s * out.tau[i] <= 5.0


@pytest.mark.slow
@pytest.mark.parametrize("engine", ["pinocchio", "mujoco"])
@pytest.mark.parametrize("base", ["sim3_zmp", "sim1_zmp"])
def test_the_balance_walk_with_motors_completes(engine: str, base: str, tmp_path: Path) -> None:
    """The catalogue motor set of sim3_zmp_motors.yaml on sim3_zmp and sim1_zmp, on both engines: the walk
    completes, the controller planned with the rotor inertias, and the sizing card gives every motored joint's
    verdict, the electrical energy and the electrical cost of transport."""
    doc = read_yaml(PARAMS / "sim3_zmp_motors.yaml")
    doc.update({"base": str(PARAMS / f"{base}.yaml"), "name": f"{base}_motors"})
    run = hs.run_walk(_file(tmp_path, doc), engine=engine, verbose=False)
    assert run.status.value == "completed", run.result.reason
    a = run.summary["design"]["actuators"]
    assert set(a["joints"]) == set(THETA_NAMES)
    assert a["electrical_energy_drawn_J"] > run.summary["design"]["walk"]["work_positive_J"]   # losses on top
    assert 0.3 < a["electrical_cost_of_transport"] < 20.0
    print(base, engine, "electrical CoT", a["electrical_cost_of_transport"], "failing", a["failing"])


@pytest.mark.slow
def test_a_knee_motor_too_weak_for_the_walk_is_reported(tmp_path: Path) -> None:
    """The Mini Cheetah's knee actuator (28 N m stall) on the knees of sim3_zmp, whose knees need 50 N m: the run
    says which joint fell short, when and by how much, and the card fails that motor."""
    doc = {"base": str(PARAMS / "sim3_zmp.yaml"), "actuators": {"joints": {"knee": "mini_cheetah_knee"}}}
    run = hs.run_walk(_file(tmp_path, doc), verbose=False)
    a = run.summary["design"]["actuators"]
    short = {s["joint"]: s for s in a["envelope_shortfalls"]}
    assert {"theta11", "theta12"} & set(short), a["envelope_shortfalls"]
    worst = max(s["worst_shortfall_Nm"] for s in short.values())
    print("status", run.status.value, "shortfalls",
          {k: (v["first_s"], v["worst_shortfall_Nm"]) for k, v in short.items()})
    assert worst > 5.0 and not a["passed"]
    assert all(0.0 <= s["first_s"] <= s["worst_at_s"] <= s["last_s"] for s in short.values())


def _file(folder: Path, doc: dict) -> Path:
    """``doc`` written as a scenario file (its ``base`` an absolute path)."""
    import yaml

    path = folder / "scenario.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path
