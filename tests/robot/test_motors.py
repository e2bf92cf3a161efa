"""The joint actuator model (humanoid_sim.robot.motors): envelope corners, power bookkeeping, the exact thermal update,
the sourced catalogue, and the acceptance check against MuJoCo's dcmotor actuator along a 60 s pendulum profile."""

from __future__ import annotations

import dataclasses
import math
import re

import mujoco
import numpy as np
import pytest

from humanoid_sim.errors import InputError
from humanoid_sim.robot.motors import (
    MotorSpec,
    assess,
    current_at_voltage,
    joint_torque,
    load_catalogue,
    motor_current,
    power_flow,
    resistance_at,
    saturate,
    terminal_voltage,
    torque_envelope,
    winding_temperature,
)

BASE = dict(gear_ratio=10.0, rotor_inertia=5e-5, efficiency=0.8, coulomb_friction=0.3, viscous_friction=0.05,
            torque_constant=0.1, resistance=0.5, bus_voltage=24.0, peak_current=20.0, continuous_current=8.0,
            thermal_resistance=2.0, thermal_capacitance=15.0, ambient_temperature=25.0,
            max_winding_temperature=125.0, reference_temperature=25.0, temperature_coefficient=0.00393)


def spec(**changes) -> MotorSpec:
    return MotorSpec(**{**BASE, **changes}, name="test")


# --- the record -----------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("field, value, expected", [
    ("gear_ratio", 0.0, "> 0"), ("efficiency", 1.2, "0 < efficiency <= 1"), ("efficiency", 0.0, "0 < efficiency"),
    ("rotor_inertia", -1e-6, ">= 0"), ("viscous_friction", -0.1, ">= 0"), ("resistance", float("nan"), "finite"),
    ("continuous_current", 30.0, "<= peak_current"), ("max_winding_temperature", 20.0, "> ambient_temperature"),
    ("torque_constant", "0.1", "a finite number"),
])
def test_a_bad_field_is_named_with_its_value_and_what_was_expected(field, value, expected) -> None:
    with pytest.raises(InputError, match=rf"MotorSpec 'test': {field} is {re.escape(repr(value))}; expected .*"
                                          rf"{re.escape(expected)}"):
        spec(**{field: value})


def test_derived_quantities() -> None:
    s = spec()
    assert s.reflected_inertia == pytest.approx(100 * 5e-5, rel=1e-15)
    assert s.no_load_speed == pytest.approx(24.0 / (0.1 * 10), rel=1e-15)
    assert s.stall_torque == pytest.approx(10 * 0.8 * 0.1 * 20, rel=1e-15)          # I_max < U/R = 48 A
    assert spec(bus_voltage=5.0).stall_torque == pytest.approx(10 * 0.8 * 0.1 * 10, rel=1e-15)   # U/R = 10 A binds
    assert s.thermal_time_constant == 30.0
    assert resistance_at(s, 125.0) == pytest.approx(0.5 * 1.393, rel=1e-15)


# --- current and torque ---------------------------------------------------------------------------------------------

def test_motoring_divides_by_the_efficiency_and_braking_multiplies() -> None:
    s = spec(coulomb_friction=0.0, viscous_friction=0.0)
    # motoring: torque and speed agree; braking: the load back-drives the motor; standstill counts as motoring
    assert motor_current(s, 8.0, 2.0) == pytest.approx(8.0 / (10 * 0.8) / 0.1, rel=1e-15)
    assert motor_current(s, 8.0, -2.0) == pytest.approx(8.0 * 0.8 / 10 / 0.1, rel=1e-15)
    assert motor_current(s, -8.0, 0.0) == pytest.approx(-8.0 / (10 * 0.8) / 0.1, rel=1e-15)
    # the friction is added before the gearbox and opposes the motion; the rotor's inertia after it
    f = spec()
    assert motor_current(f, 8.0, 2.0, accel=100.0) == pytest.approx(
        ((8.0 + 0.3 + 0.05 * 2) / 8 + 5e-5 * 10 * 100) / 0.1, rel=1e-14)
    assert motor_current(f, 0.0, -1.0) == pytest.approx(-(0.3 + 0.05) / 8 / 0.1, rel=1e-14)


def test_joint_torque_inverts_the_current() -> None:
    rng = np.random.default_rng(3)
    tau, omega, accel = rng.normal(0, 10, 2000), rng.normal(0, 5, 2000), rng.normal(0, 50, 2000)
    s = spec()
    back = joint_torque(s, motor_current(s, tau, omega, accel), omega, accel)
    assert np.max(np.abs(back - tau)) < 1e-12      # round-off of a few products


def test_voltage_and_current_invert_each_other() -> None:
    s = spec()
    volts = terminal_voltage(s, 7.0, 3.0, temperature=80.0)
    assert volts == pytest.approx(resistance_at(s, 80.0) * 7.0 + 0.1 * 10 * 3.0, rel=1e-15)
    assert current_at_voltage(s, volts, 3.0, temperature=80.0) == pytest.approx(7.0, rel=1e-14)


# --- the envelope ---------------------------------------------------------------------------------------------------

def test_envelope_corners_stall_torque_and_no_load_speed() -> None:
    s = spec(efficiency=1.0, coulomb_friction=0.0, viscous_friction=0.0, rotor_inertia=0.0)
    env = torque_envelope(s, [0.0, s.no_load_speed, -s.no_load_speed])
    assert env.tau_max[0] == pytest.approx(s.stall_torque, rel=1e-15)
    assert env.tau_min[0] == pytest.approx(-s.stall_torque, rel=1e-15)
    assert env.tau_max[1] == pytest.approx(0.0, abs=1e-12)       # no current left at the no-load speed
    assert env.tau_min[2] == pytest.approx(0.0, abs=1e-12)
    # between the corners the back-EMF bounds the current: tau = N k_t (U - k_t N omega) / R
    omega = np.linspace(0.0, s.no_load_speed, 50)
    volt_limited = 10 * 0.1 * (24.0 - 0.1 * 10 * omega) / 0.5
    assert np.allclose(torque_envelope(s, omega).tau_max, np.minimum(s.stall_torque, volt_limited), rtol=1e-14)


def test_envelope_with_losses_and_a_hot_winding() -> None:
    s = spec()
    omega = 1.5
    env = torque_envelope(s, omega)
    # motoring side at the current limit, less the friction the drive overcomes first
    assert env.tau_max == pytest.approx(10 * 0.8 * 0.1 * 20 - (0.3 + 0.05 * omega), rel=1e-14)
    # braking side: the current limit's torque arrives multiplied through the gearbox by 1/eta
    assert env.tau_min == pytest.approx(-10 / 0.8 * 0.1 * 20 - (0.3 + 0.05 * omega), rel=1e-14)
    # accelerating the rotor takes N^2 J_r alpha (through the gearbox) off what reaches the load
    assert torque_envelope(s, 0.0, accel=200.0).tau_max == pytest.approx(
        torque_envelope(s, 0.0).tau_max - 10 * 0.8 * 5e-5 * 10 * 200.0, rel=1e-14)
    # a hot winding narrows the voltage-limited part of the envelope
    fast = 0.9 * s.no_load_speed
    assert torque_envelope(s, fast, temperature=120.0).tau_max < torque_envelope(s, fast).tau_max


def test_saturate_reports_mask_and_shortfall() -> None:
    s = spec()
    cmd = np.array([5.0, 50.0, -50.0])
    out = saturate(s, cmd, 0.0)
    env = torque_envelope(s, 0.0)
    assert out.saturated.tolist() == [False, True, True]
    assert out.torque.tolist() == [5.0, float(env.tau_max), float(env.tau_min)]
    assert np.array_equal(out.shortfall, cmd - out.torque)


# --- power ----------------------------------------------------------------------------------------------------------

def test_electrical_power_is_mechanical_power_plus_losses() -> None:
    rng = np.random.default_rng(7)
    n = 5000
    tau, omega, accel = rng.normal(0, 10, n), rng.normal(0, 5, n), rng.normal(0, 50, n)
    flow = power_flow(spec(), tau, omega, accel, temperature=rng.uniform(25, 120, n))
    scale = np.max(np.abs(flow.electrical))
    assert flow.residual() < 1e-12 * scale            # the same products summed in another order
    assert np.all(flow.friction >= 0) and np.all(flow.gear >= -1e-12 * scale) and np.all(flow.copper >= 0)
    assert np.any(flow.electrical < 0)                # braking samples regenerate


def test_regeneration_counts_in_the_net_energy_only() -> None:
    s = spec()
    # lowering a load: negative power at the joint, so the motor brakes and feeds the bus back
    report = assess(s, tau=np.full(100, -6.0), omega=np.full(100, 3.0), dt=0.01)
    assert report.energy_net < 0 and report.energy_drawn == 0.0     # every sample regenerates
    lifting = assess(s, tau=np.full(100, 6.0), omega=np.full(100, 3.0), dt=0.01)
    assert lifting.energy_net == pytest.approx(lifting.energy_drawn, rel=1e-15)
    assert lifting.energy_net > 6.0 * 3.0 * 1.0       # more than the 18 J delivered to the load


# --- heat -----------------------------------------------------------------------------------------------------------

def test_thermal_steady_state_and_time_constant_match_the_closed_form() -> None:
    s = spec(temperature_coefficient=0.0)
    current, loss = 6.0, 6.0**2 * 0.5
    tau = s.thermal_time_constant
    # one step of tau and many small steps both land on T_amb + P R_th (1 - e^-1): the update is exact
    one = winding_temperature(s, [current], tau)[-1]
    many = winding_temperature(s, np.full(3000, current), tau / 3000)[-1]
    closed = 25.0 + loss * 2.0 * (1 - math.exp(-1))
    assert one == pytest.approx(closed, abs=1e-12) and many == pytest.approx(closed, abs=1e-10)
    steady = winding_temperature(s, np.full(100, current), tau)[-1]      # 100 time constants
    assert steady == pytest.approx(25.0 + loss * 2.0, abs=1e-10)
    # cooling from a hot start decays with the same time constant
    cool = winding_temperature(s, [0.0], tau, initial=85.0)[-1]
    assert cool == pytest.approx(25.0 + 60.0 * math.exp(-1), abs=1e-12)


def test_a_resistance_rising_with_temperature_is_integrated_exactly() -> None:
    s = spec()
    current, h = 6.0, 0.7
    # dtheta/dt = a - b theta (theta = T - T_amb; T_amb = T_ref here)
    a = 0.5 * current**2 / 15.0
    b = (1 / 2.0 - 0.00393 * 0.5 * current**2) / 15.0
    temps = winding_temperature(s, np.full(200, current), h)
    t = h * np.arange(1, 201)
    assert np.allclose(temps, 25.0 + a / b * (1 - np.exp(-b * t)), rtol=0, atol=1e-11)
    # past the runaway current 1/sqrt(alpha R R_th) the winding has no steady state
    runaway = winding_temperature(s, np.full(50, 1.05 / math.sqrt(0.00393 * 0.5 * 2.0)), 10.0)
    assert np.all(np.diff(np.diff(runaway)) > 0)


# --- the per-joint report -------------------------------------------------------------------------------------------

def test_assess_reports_peaks_rms_margins_and_energy() -> None:
    s = spec(coulomb_friction=0.0, viscous_friction=0.0, efficiency=1.0)
    t = np.arange(0, 10, 0.001)
    tau, omega = 10 * np.sin(2 * np.pi * t), 2 * np.cos(2 * np.pi * t)
    r = assess(s, tau, omega, 0.001)
    assert r.peak_current == pytest.approx(10.0, rel=1e-6)                 # 10 N m / (N k_t) = 10 A
    assert r.rms_current == pytest.approx(10 / math.sqrt(2), rel=1e-6)
    assert r.rms_ratio == pytest.approx(r.rms_current / 8.0, rel=1e-15)
    assert r.current_margin == pytest.approx(0.5, rel=1e-6)
    assert r.speed_margin == pytest.approx(1 - 2 / 24, rel=1e-9)           # no-load speed 24 rad/s
    assert r.passed and r.failures == [] and r.saturated_fraction == 0.0
    assert 25.0 < r.peak_temperature < 125.0 and 0 < r.temperature_margin < 1
    # the net energy is the copper loss (the load's power averages to zero over whole periods), at a resistance
    # between the cold and the hottest one
    cold = float(np.sum(motor_current(s, tau, omega) ** 2 * 0.5 * 0.001))
    assert cold < r.energy_net < cold * float(resistance_at(s, r.peak_temperature)) / 0.5
    weak = assess(spec(peak_current=9.0, continuous_current=5.0), tau, omega, 0.001)
    assert not weak.passed and {f.split(":")[0] for f in weak.failures} >= {"torque", "current", "rms"}
    with pytest.raises(InputError, match="expected at least one sample and positive steps"):
        assess(s, tau, omega, 0.0)


# --- the catalogue --------------------------------------------------------------------------------------------------

def test_catalogue_has_a_knee_sized_actuator_and_a_too_weak_one() -> None:
    cat = load_catalogue()
    assert 3 <= len(cat) <= 6
    knee = cat["osl_knee"]
    # the thesis knee peaks at about 50 N m at 2-3 rad/s (docs/notes/2026-11-26-designer.md)
    assert np.all(torque_envelope(knee, [0.0, 2.0, 3.0], temperature=knee.ambient_temperature).tau_max > 50.0)
    assert cat["mini_cheetah_knee"].stall_torque < 50.0 and cat["mini_cheetah_hip"].stall_torque < 50.0


def test_catalogue_entries_need_a_source_for_every_number(tmp_path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("m:\n  gear_ratio: {value: 9}\n")
    with pytest.raises(InputError, match=r"'m': gear_ratio is \{'value': 9\}; expected \{value: <number>, source"):
        load_catalogue(path)
    path.write_text("m:\n  gear_ratios: {value: 9, source: x}\n")
    with pytest.raises(InputError, match=r"unknown field\(s\) \['gear_ratios'\]"):
        load_catalogue(path)
    with pytest.raises(InputError, match="cannot read"):
        load_catalogue(tmp_path / "missing.yaml")


# --- the acceptance check against MuJoCo's dcmotor ------------------------------------------------------------------

MASS, ARM, INERTIA_CM, GRAVITY = 2.0, 0.25, 0.01, 9.81     # the pendulum: kg, m (hinge to COM), kg m^2, m/s^2
AMPLITUDES = np.array([0.8, 0.4, 0.25])                     # rad
OMEGAS = 2 * np.pi * np.array([0.7, 1.6, 0.23])             # rad/s
PHASES = np.array([0.0, 0.5, 1.0])


def dcmotor_mjcf(s: MotorSpec, timestep: float) -> str:
    """A one-hinge pendulum driven by MuJoCo's dcmotor with ``s``'s parameters (the mapping of the note).

    gear = N; motorconst = k_t (= k_e); resistance = R at T_ref; thermal = R_th C_th, alpha_Cu, T_ref, T_amb;
    armature = J_r (MuJoCo adds gear^2 armature to the joint); damping = viscous / N^2 (MuJoCo's actuator damping is
    motor side, scaled by gear^2); ctrlrange = +-U (the bus). Not mapped: efficiency and Coulomb friction (dcmotor has
    neither), I_max (dcmotor's saturation clamps the torque but heats with the unclamped current), I_cont and the
    temperature limit (no equivalent); no inductance on either side, so both currents are algebraic.
    """
    return f"""<mujoco>
  <option timestep="{timestep!r}" integrator="RK4" gravity="0 0 {-GRAVITY!r}"/>
  <worldbody>
    <body name="link">
      <joint name="hinge" type="hinge" axis="0 1 0"/>
      <inertial pos="{ARM!r} 0 0" mass="{MASS!r}" diaginertia="{INERTIA_CM!r} {INERTIA_CM!r} {INERTIA_CM!r}"/>
    </body>
  </worldbody>
  <actuator>
    <dcmotor name="drive" joint="hinge" gear="{s.gear_ratio!r}" motorconst="{s.torque_constant!r}"
             resistance="{s.resistance!r}" armature="{s.rotor_inertia!r}"
             damping="{s.viscous_friction / s.gear_ratio**2!r}"
             thermal="{s.thermal_resistance!r} {s.thermal_capacitance!r} 0 {s.temperature_coefficient!r}
                      {s.reference_temperature!r} {s.ambient_temperature!r}"
             ctrllimited="true" ctrlrange="{-s.bus_voltage!r} {s.bus_voltage!r}"/>
  </actuator>
</mujoco>"""


def reference(t: float) -> tuple[float, float, float]:
    """The joint's 60 s target: a sum of three sines (rad, rad/s, rad/s^2)."""
    s, c = np.sin(OMEGAS * t + PHASES), np.cos(OMEGAS * t + PHASES)
    return float(AMPLITUDES @ s), float(AMPLITUDES * OMEGAS @ c), float(-(AMPLITUDES * OMEGAS**2) @ s)


def test_model_agrees_with_mujoco_dcmotor_over_a_60_s_profile() -> None:
    """MuJoCo drives the pendulum along the target by its terminal voltage; the model, fed the same joint speed,
    acceleration and link torque, gives the current, the torque the voltage delivers, and the winding temperature."""
    s = dataclasses.replace(load_catalogue()["mini_cheetah_knee"], coulomb_friction=0.0)   # the common subset
    h, steps = 0.001, 60_000
    model = mujoco.MjModel.from_xml_string(dcmotor_mjcf(s, h))
    data = mujoco.MjData(model)
    inertia = INERTIA_CM + MASS * ARM**2                     # about the hinge
    n, k = s.gear_ratio, s.torque_constant
    data.qpos[0], data.qvel[0], _ = reference(0.0)
    log = np.empty((steps, 8))
    for i in range(steps):
        q_ref, v_ref, a_ref = reference(i * h)
        q, v = float(data.qpos[0]), float(data.qvel[0])
        # the drive: computed torque with PD feedback, turned into a voltage with MuJoCo's own winding temperature
        accel = a_ref + 400 * (q_ref - q) + 40 * (v_ref - v)
        motor = (inertia * accel - MASS * GRAVITY * ARM * math.cos(q) + s.reflected_inertia * accel
                 + s.viscous_friction * v) / n
        r_hot = float(resistance_at(s, data.act[0] + s.ambient_temperature))
        data.ctrl[0] = r_hot * motor / k + k * n * v
        mujoco.mj_forward(model, data)                      # the values the step starts from
        log[i, :7] = (q, q_ref, v, data.qacc[0], data.ctrl[0], data.actuator_force[0],
                      data.qfrc_actuator[0] + data.qfrc_passive[0])
        mujoco.mj_step(model, data)
        log[i, 7] = data.act[0] + s.ambient_temperature    # the winding temperature at the step's end
    q, q_ref, omega, alpha, volts, force, drive, temp_mj = log.T
    assert np.max(np.abs(q - q_ref)) < 5e-3                 # it followed the target (PD lag of one step)
    assert np.max(np.abs(volts)) < s.bus_voltage            # and the bus never clipped the voltage

    link_torque = inertia * alpha - MASS * GRAVITY * ARM * np.cos(q)     # the pendulum's own inverse dynamics
    current = motor_current(s, link_torque, omega, accel=alpha)
    temp = winding_temperature(s, current, h)
    temp_start = np.concatenate(([s.ambient_temperature], temp[:-1]))
    torque = joint_torque(s, current_at_voltage(s, volts, omega, temp_start), omega, accel=alpha)
    current_mj = force / k                                   # the stateless dcmotor's force is K I
    torque_mj = drive - s.reflected_inertia * alpha          # what reaches the link past the rotor and the damping

    current_err = np.max(np.abs(current - current_mj)) / np.max(np.abs(current_mj))
    torque_err = np.max(np.abs(torque - torque_mj)) / np.max(np.abs(torque_mj))
    temp_err = np.max(np.abs(temp - temp_mj))
    assert temp_mj[-1] - s.ambient_temperature > 10.0       # a profile that heats the winding measurably
    # the acceptance: 1 % of the peak (a pointwise ratio is undefined at the zero crossings) and 1 K
    assert current_err < 0.01 and torque_err < 0.01 and temp_err < 1.0
    # what was measured (docs/notes/2026-11-26-motors.md): the current is the same algebra (round-off); the torque
    # inherits the temperature difference through R(T); the temperature differs at first order in the step because
    # MuJoCo holds the voltage over a step (its current drifts with the back-EMF) and the model holds the current
    assert current_err < 1e-12 and torque_err < 1e-3 and temp_err < 0.2
