"""The designer's numbers of a run: per joint the torque, speed, power, work and the loads its bearing carries; for
the walk the mechanical work and cost of transport; the ground's peak forces; fatigue cycles and load cases.

Everything is taken over the run's full-rate trace (:mod:`humanoid_sim.interfaces.trace`: every MuJoCo step, every
integration step of the weld engine), so a peak between two log rows is not missed.

Definitions (SI units; per joint = per thesis joint variable theta_i, a revolute axis, the axis a motor drives):

- torque: the generalized torque about the joint's axis, in the sign of theta_i (N m); speed: theta_i's rate
  (rad/s); power: torque x speed (W; > 0 when the actuator drives the joint, < 0 when it brakes it);
- positive / negative work: the time integrals of the positive / negative parts of the power (J), by the
  trapezoidal rule over the trace's rows (second order: over a single support of the thesis gait on welds the
  joints' net work matches the change of mechanical energy to 0.1 % at 10 ms; holding each row's power over its
  step misses it by 17 %);
- RMS: the root of the time mean of the square over the run;
- joint loads: the wrench the parent side transmits to the child body across the joint, in the joint's frame, split
  along the joint axis (:func:`humanoid_sim.dynamics.joint_loads.bearing_loads`): axial force, shear (radial)
  force, torsion (the torque about the axis) and bending (tilting) moment about the joint origin;
- distance travelled: the horizontal path length of the midpoint between the two toe points, sampled at the start,
  at every phase change and at the end (the walk line through the footholds, free of the pelvis's sway);
- mechanical cost of transport: total positive joint work / (m g distance), m the robot's mass;
- fatigue: rainflow cycles (ASTM E1049, the ``rainflow`` package) of each joint's torque and of its bending moment,
  counted per range bin and scaled to one kilometre of walking at this gait;
- settling: on real ground (MuJoCo) the robot starts at rest with its soles just touching a soft ground, which
  pushes back within the first milliseconds (sim3_zmp: the right toe spins at 16 rad/s and the right ankle takes
  226 W at t = 1 ms).  That is the start of the simulation, not of a walk: the numbers above exclude the engine's
  settling window (on MuJoCo ten contact time constants, 0.05 s: :func:`humanoid_sim.engines.mujoco.ground.
  settling_time`; none on welded feet) and the card reports its peaks apart.

The thesis's actuator torques T (eq. 4.69, Cartesian components of a joint's moment) keep their own peaks in the
summary (``torque_peak_Nm``, against their saturation limits); at the spherical joints (ankles, hips, waist, neck)
an axis's torque and the component of the same name differ by the axes' misalignment in the current posture.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from humanoid_sim.dynamics.joint_loads import JointLoads, fext_from_body_wrenches, joint_loads
from humanoid_sim.interfaces.trace import Trace
from humanoid_sim.robot.actuators import GROUPS, T_NAMES, Actuators
from humanoid_sim.robot.model import THETA_NAMES, HumanoidModel
from humanoid_sim.robot.motors import MotorSpec

GRAVITY = 9.81
"""m/s^2, for the cost of transport's weight (the model's own gravity is the same magnitude)."""

FATIGUE_BINS = 10
"""Range bins of the fatigue table: equal tenths of each joint's largest range."""

LOAD_CASE_KEYS = ("axial_N", "shear_N", "torsion_Nm", "bending_Nm")
"""The criteria a joint's worst load cases are picked by (largest magnitude of each)."""


def joint_label(theta: str) -> str:
    """A thesis joint variable with the joint it belongs to, e.g. ``"theta11 (right_knee)"``."""
    for g in GROUPS:
        if theta in g.thetas:
            return f"{theta} ({g.name})"
    return theta


def joint_limits() -> dict[str, tuple[str, int]]:
    """Per thesis joint variable: the thesis actuator torque that acts about the same axis at the reference
    posture (the group's component in the same position) and its index in T-bar order."""
    out = {}
    for g in GROUPS:
        for th, name in zip(g.thetas, g.T):
            out[th] = (name, T_NAMES.index(name))
    return out


class DesignCard(NamedTuple):
    """A run's design numbers (module docstring).

    Attributes:
        joints: per thesis joint variable (eq. 4.1 order) a dict of its numbers (keys with units).
        walk: totals of the walk (work, distance, cost of transport, mass, ground peaks).
        rates: where the numbers come from (the trace's period and source, the log's period).
        fatigue: rows (joint, quantity, range bin low / high, cycles per km).
        settling: the start-up window's length and its peaks per joint (torque, speed, power), reported apart.
        load_cases: per joint and criterion the worst instant: time, wrench in the joint frame, configuration.
        series: the full-rate series the figures draw (t, torque, speed, power: (n, 26) each).
        actuators: with the scenario's motors, per motored joint the motor's verdict over the walk
            (:func:`motor_section`), the walk's electrical energy and cost of transport, where the envelope fell
            short; None without motors.
    """

    joints: list[dict[str, Any]]
    walk: dict[str, Any]
    rates: dict[str, Any]
    fatigue: list[dict[str, Any]]
    load_cases: dict[str, Any]
    series: dict[str, np.ndarray]
    settling: dict[str, Any]
    actuators: dict[str, Any] | None = None

    def summary(self) -> dict[str, Any]:
        """The ``design`` section of summary.json (JSON types; the load cases and fatigue go to their own files)."""
        out = {"definitions": "humanoid_sim.analysis.design (docs: outputs, 'The sizing card')",
               "rates": self.rates, "walk": self.walk, "settling": self.settling,
               "joints": {row["joint"]: {k: v for k, v in row.items() if k != "joint"} for row in self.joints}}
        if self.actuators is not None:
            out["actuators"] = self.actuators
        return out


def _f(x: Any) -> float | None:
    x = float(x)
    return x if np.isfinite(x) else None


def walk_distance(log: dict[str, np.ndarray]) -> float:
    """Horizontal path length (m) of the toe points' midpoint at the start, at each phase change and at the end."""
    if len(log["t"]) < 2:
        return 0.0
    mid = 0.5 * (np.asarray(log["toe_R_p"])[:, :2] + np.asarray(log["toe_L_p"])[:, :2])
    phase = np.asarray(log["phase"])
    idx = np.concatenate([[0], np.flatnonzero(np.diff(phase)) + 1, [len(mid) - 1]])
    pts = mid[np.unique(idx)]
    return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())


def rainflow_table(series: np.ndarray, per_km: float, bins: int = FATIGUE_BINS) -> list[tuple[float, float, float]]:
    """(range low, range high, cycles per km) per bin of equal width up to the largest range: the ASTM E1049 rainflow
    count of ``series`` (``rainflow.extract_cycles``; half cycles count 0.5) times ``per_km`` (km^-1: the walks of
    this length in a kilometre).  Empty for a series without a cycle (constant)."""
    import rainflow

    cycles = np.array([(rng, count) for rng, _mean, count, _i, _j in rainflow.extract_cycles(np.asarray(series,
                                                                                                           dtype=float))])
    if not len(cycles) or not cycles[:, 0].max() > 0:
        return []
    counts, edges = np.histogram(cycles[:, 0], bins=bins, range=(0.0, float(cycles[:, 0].max())), weights=cycles[:, 1])
    return [(float(lo), float(hi), float(n) * per_km) for lo, hi, n in zip(edges[:-1], edges[1:], counts)]


def design_card(trace: Trace, log: dict[str, np.ndarray], hm: HumanoidModel, settling_s: float = 0.0,
                motors: dict[str, MotorSpec] | None = None,
                shortfalls: list[dict[str, Any]] | None = None) -> DesignCard:
    """The design numbers of a run (module docstring).

    Args:
        trace: the run's full-rate trace (``SimResult.trace``).
        log: the run's log arrays (``SimLog.arrays()``): the toe points at phase changes give the distance.
        hm: the robot model.
        settling_s: the start-up window to leave out of the walk's numbers and report apart, s (the engine's
            settling window on real ground, 0 on welded feet).
        motors: the scenario's motors by thesis joint variable (:mod:`humanoid_sim.scenario.actuators`), or None.
        shortfalls: where the motors' envelopes clipped the controller (``SimResult.extra["actuators"]``).

    Returns:
        The :class:`DesignCard`.
    """
    full = trace.columns
    dt = trace.period_s
    t_all = np.asarray(full["t"])
    keep = t_all >= settling_s - 1e-12
    c = {k: np.asarray(v)[keep] for k, v in full.items()}
    settling = _settling(full, ~keep, hm, settling_s)
    model = hm.model
    vidx, sign = np.asarray(hm.theta_v_idx), np.asarray(hm.theta_sign)
    torque = sign * np.asarray(c["tau"])[:, vidx]
    speed = sign * np.asarray(c["v"])[:, vidx]
    power = torque * speed
    duration = len(torque) * dt
    loads: JointLoads = joint_loads(model, c["q"], c["v"], c["a"],
                                    fext_from_body_wrenches(model, c["body_force"], c["body_moment"]),
                                    joints=list(THETA_NAMES))
    bearing = loads.bearing()
    limits = joint_limits()
    act_limits = Actuators(hm).limits
    distance = walk_distance(log)
    per_km = 1000.0 / distance if distance > 0.05 else 0.0   # below 5 cm the walk did not go anywhere
    mass = float(sum(inertia.mass for inertia in model.inertias))
    rows, fatigue, cases = [], [], {}
    t = np.asarray(c["t"])

    def rms(x: np.ndarray) -> float | None:
        return _f(np.sqrt(np.mean(x ** 2))) if len(x) else None

    for j, theta in enumerate(THETA_NAMES):
        tname, ti = limits.get(theta, ("", -1))
        limit = float(act_limits[ti]) if ti >= 0 else float("nan")
        tq, sp, pw = torque[:, j], speed[:, j], power[:, j]
        peak = float(np.abs(tq).max()) if len(tq) else float("nan")
        rows.append({
            "joint": theta, "label": joint_label(theta), "thesis_torque": tname, "limit_Nm": _f(limit),
            "torque_peak_Nm": _f(peak), "torque_rms_Nm": rms(tq), "torque_margin_Nm": _f(limit - peak),
            "speed_peak_rad_s": _f(np.abs(sp).max()) if len(sp) else None, "speed_rms_rad_s": rms(sp),
            "power_peak_W": _f(np.abs(pw).max()) if len(pw) else None,
            "power_max_W": _f(pw.max()) if len(pw) else None, "power_min_W": _f(pw.min()) if len(pw) else None,
            "work_positive_J": _f(_integral(np.clip(pw, 0, None), dt)),
            "work_negative_J": _f(_integral(np.clip(pw, None, 0), dt)),
            "axial_peak_N": _f(np.abs(bearing.axial[:, j]).max()) if len(tq) else None,
            "shear_peak_N": _f(bearing.shear[:, j].max()) if len(tq) else None,
            "torsion_peak_Nm": _f(np.abs(bearing.torsion[:, j]).max()) if len(tq) else None,
            "bending_peak_Nm": _f(bearing.bending[:, j].max()) if len(tq) else None,
        })
        if len(tq) >= 3:
            for quantity, series in (("torque_Nm", tq), ("bending_Nm", bearing.bending[:, j])):
                for lo, hi, n in rainflow_table(series, per_km):
                    fatigue.append({"joint": theta, "quantity": quantity, "range_low": lo, "range_high": hi,
                                    "cycles_per_km": n})
            worst = {}
            for key, values in zip(LOAD_CASE_KEYS, (bearing.axial[:, j], bearing.shear[:, j],
                                                    bearing.torsion[:, j], bearing.bending[:, j])):
                i = int(np.argmax(np.abs(values)))
                worst[key] = {"t_s": float(t[i]), "value": float(values[i]),
                              "wrench_N_Nm": loads.wrench[i, j].tolist(), "q": np.asarray(c["q"])[i].tolist()}
            cases[theta] = {"frame": f"joint frame of {theta} (child body, origin on the joint axis)",
                            "axis": loads.axis[j].tolist(), "worst": worst}
    fw = np.asarray(c["foot_wrench"])
    fz_total = fw[:, :, 2].sum(axis=1)
    f_horizontal = np.linalg.norm(fw[:, :, :2].sum(axis=1), axis=1)
    w_pos = float(sum(_integral(np.clip(power[:, j], 0, None), dt) for j in range(power.shape[1])))
    w_neg = float(sum(_integral(np.clip(power[:, j], None, 0), dt) for j in range(power.shape[1])))
    walk = {
        "mass_kg": mass, "duration_s": _f(duration), "distance_m": distance,
        "work_positive_J": w_pos, "work_negative_J": w_neg,
        "mechanical_cost_of_transport": _f(w_pos / (mass * GRAVITY * distance)) if per_km else None,
        "cost_of_transport_definition": "total positive joint work / (m g distance travelled)",
        "ground_force_vertical_peak_N": _f(fz_total.max()) if len(fz_total) else None,
        "ground_force_vertical_peak_per_foot_N": {f: _f(fw[:, i, 2].max()) if len(fw) else None
                                                  for i, f in enumerate(("R", "L"))},
        "ground_force_horizontal_peak_N": _f(f_horizontal.max()) if len(fz_total) else None,
        "binding_joint": _binding(rows),
    }
    rates = {"trace_period_s": dt, "trace_source": trace.source, "trace_rows": len(t),
             "log_period_s": _f(np.median(np.diff(log["t"]))) if len(log["t"]) > 1 else None,
             "log_rows": len(log["t"]),
             "from_trace": ["design", "torque_peak_Nm", "torque_cmd_peak_Nm", "saturated_fraction",
                            "saturated_fraction_per_actuator", "contact"],
             "from_log": ["hip_com_error_*", "hip_yaw_error_rms_rad", "constraint_drift_*", "phase_log"]}
    rates["settling_excluded_s"] = settling_s
    actuators = None
    if motors:
        accel = sign * np.asarray(c["a"])[:, vidx]
        rotor = np.asarray(model.armature)[vidx] * accel   # the reflected rotor inertia's share of each torque
        actuators = motor_section(motors, torque, speed, dt, mass, distance, shortfalls or [], rotor)
    return DesignCard(rows, walk, rates, fatigue, cases, {"t": t, "torque": torque, "speed": speed, "power": power},
                      settling, actuators)


def motor_section(motors: dict[str, MotorSpec], torque: np.ndarray, speed: np.ndarray, dt: float, mass: float,
                  distance: float, shortfalls: list[dict[str, Any]], rotor: np.ndarray | None = None
                  ) -> dict[str, Any]:
    """The sizing card's motor verdicts (:func:`humanoid_sim.robot.motors.assess` per motored joint over the walk:
    current, RMS current against the continuous rating, winding temperature against its limit, the margins, the
    electrical energy) and for the walk the electrical energy drawn (no regeneration) and net (regeneration returned)
    and the electrical cost of transport = energy drawn / (m g distance).

    Args:
        motors: thesis joint variable -> motor.
        torque, speed: (n, 26) joint torque (N m, including the rotor's inertia: the models carry the armature) and
            speed (rad/s), thesis order and sign, every integration step of the walk.
        dt: the rows' period, s.
        mass: the robot's mass, kg.
        distance: the distance walked, m.
        shortfalls: the drive's records of where an envelope clipped the controller.
        rotor: (n, 26) the reflected rotor inertia's share of each joint torque, N^2 J_r times the joint's
            acceleration (N m), or None.
    """
    from humanoid_sim.robot.motors import assess

    joints, drawn, net = {}, 0.0, 0.0
    for j, theta in enumerate(THETA_NAMES):
        spec = motors.get(theta)
        if spec is None or not len(torque):
            continue
        r = assess(spec, torque[:, j], speed[:, j], dt)
        joints[theta] = {"motor": spec.name, "peak_current_A": r.peak_current, "rms_current_A": r.rms_current,
                         "rms_over_continuous": r.rms_ratio, "peak_winding_temperature_C": r.peak_temperature,
                         "winding_temperature_limit_C": r.temperature_limit, "torque_margin": r.torque_margin,
                         "speed_margin": r.speed_margin, "current_margin": r.current_margin,
                         "rms_margin": r.rms_margin, "temperature_margin": r.temperature_margin,
                         "electrical_energy_drawn_J": r.energy_drawn, "electrical_energy_net_J": r.energy_net,
                         "outside_envelope_fraction": r.saturated_fraction, "passed": r.passed,
                         "failures": r.failures, "reflected_inertia_kg_m2": spec.reflected_inertia}
        if rotor is not None:
            joints[theta]["rotor_torque_peak_Nm"] = _f(np.abs(rotor[:, j]).max())
            joints[theta]["rotor_torque_rms_Nm"] = _f(np.sqrt(np.mean(rotor[:, j] ** 2)))
        drawn += r.energy_drawn
        net += r.energy_net
    failing = [f"{th} ({v['motor']}): {'; '.join(_why(v, motors[th]))}" for th, v in joints.items()
               if not v["passed"]]
    return {"joints": joints, "passed": not failing and not shortfalls, "failing": failing,
            "envelope_shortfalls": shortfalls, "electrical_energy_drawn_J": drawn, "electrical_energy_net_J": net,
            "electrical_cost_of_transport": drawn / (mass * GRAVITY * distance) if distance > 0.05 else None,
            "electrical_cost_of_transport_definition": "electrical energy drawn by the motors, no regeneration, / "
                                                       "(m g distance travelled)"}


def _settling(c: dict[str, np.ndarray], rows: np.ndarray, hm: HumanoidModel, settling_s: float) -> dict[str, Any]:
    """Peaks of the start-up window (torque, speed, power per joint; total vertical ground force)."""
    out: dict[str, Any] = {"window_s": settling_s, "rows": int(rows.sum())}
    if not rows.any():
        return out
    vidx, sign = np.asarray(hm.theta_v_idx), np.asarray(hm.theta_sign)
    tq = sign * np.asarray(c["tau"])[rows][:, vidx]
    sp = sign * np.asarray(c["v"])[rows][:, vidx]
    pw = np.abs(tq * sp)
    out["ground_force_vertical_peak_N"] = _f(np.asarray(c["foot_wrench"])[rows][:, :, 2].sum(axis=1).max())
    out["joints"] = {th: {"torque_peak_Nm": _f(np.abs(tq[:, j]).max()), "speed_peak_rad_s": _f(np.abs(sp[:, j]).max()),
                          "power_peak_W": _f(pw[:, j].max())} for j, th in enumerate(THETA_NAMES)}
    return out


def _why(v: dict[str, Any], spec: MotorSpec) -> list[str]:
    """A failing motor's checks in words, with the numbers behind each margin.  A motor the drive held at its
    envelope fails by a hair: the torque set at a control update's speed lies just past the envelope at the speeds
    of the period's later steps (0.0004 N m on sim3_zmp's toes); the words give the size."""
    out = []
    if v["torque_margin"] < 0:
        out.append(f"torque beyond its envelope by up to {-v['torque_margin'] * spec.stall_torque:.2g} N m "
                   f"(in {100 * v['outside_envelope_fraction']:.2g} % of the steps)")
    if v["speed_margin"] < 0:
        out.append(f"speed beyond its no-load speed {spec.no_load_speed:.3g} rad/s")
    if v["current_margin"] < 0:
        out.append(f"peak current {v['peak_current_A']:.4g} A, {v['peak_current_A'] - spec.peak_current:.2g} A above "
                   f"its limit {spec.peak_current:.4g} A")
    if v["rms_margin"] < 0:
        out.append(f"RMS current {v['rms_current_A']:.3g} A, {v['rms_over_continuous']:.2f} x its continuous rating "
                   f"{spec.continuous_current:g} A (it overheats on a longer walk)")
    if v["temperature_margin"] < 0:
        out.append(f"winding at {v['peak_winding_temperature_C']:.1f} C, above its limit "
                   f"{spec.max_winding_temperature:g} C")
    return out


def _integral(x: np.ndarray, dt: float) -> float:
    """Trapezoidal integral of evenly spaced samples (0 for fewer than two)."""
    return float(dt * (x.sum() - 0.5 * (x[0] + x[-1]))) if len(x) > 1 else 0.0


def _binding(rows: list[dict[str, Any]]) -> dict[str, Any] | None:
    """The joint with the smallest torque margin (its name, peak, limit and margin as a fraction of the limit)."""
    ok = [r for r in rows if r["torque_margin_Nm"] is not None and r["limit_Nm"]]
    if not ok:
        return None
    r = min(ok, key=lambda r: r["torque_margin_Nm"] / r["limit_Nm"])
    return {"joint": r["label"], "torque_peak_Nm": r["torque_peak_Nm"], "limit_Nm": r["limit_Nm"],
            "margin_fraction": r["torque_margin_Nm"] / r["limit_Nm"]}


__all__ = ["DesignCard", "design_card", "joint_label", "joint_limits", "motor_section", "rainflow_table",
           "walk_distance"]
