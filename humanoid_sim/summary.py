"""summary.json: the numbers a user reads first after a run (tracking, torques, contacts, speed)."""

from __future__ import annotations

from typing import Any

import numpy as np

from humanoid_sim.actuators import T_NAMES
from humanoid_sim.simulate import SimResult


def _f(x: Any) -> float | None:
    x = float(x)
    return x if np.isfinite(x) else None


def summarize(result: SimResult, scenario_name: str, engine: str) -> dict[str, Any]:
    """Summary of a run (SI units: m, rad, N m, s).  Runs on an engine with real contact (``--engine mujoco``) add
    ``fell``, ``fall_time_s``, ``fall_reason``, ``foot_slip_max_m``, ``foot_tilt_max_rad``, ``penetration_max_m``
    and ``control_period_s`` (:meth:`humanoid_sim.engines.mujoco.MujocoEngine.run_info`)."""
    a = result.log.arrays()
    n = len(result.log)
    out: dict[str, Any] = {
        "scenario": scenario_name,
        "engine": engine,
        "completed": bool(result.completed),
        "reason": result.reason,
        "phases_planned": int(result.phases_planned),
        "phases_completed": int(sum(1 for p in result.phases if p.t_end is not None and (
            p is not result.phases[-1] or result.completed))),
        "sim_time_s": _f(result.sim_time),
        "wall_time_s": _f(result.wall_time),
        "real_time_factor": _f(result.sim_time / result.wall_time) if result.wall_time > 0 else None,
        "steps": int(result.steps),
    }
    if "compiled_stages" in result.extra:  # fast engine: how many stages ran compiled (kernel/), how many not
        out["compiled_stages"] = int(result.extra["compiled_stages"])
        out["reference_stages"] = int(result.stage_evaluations - result.extra["compiled_stages"])
    if n:
        e = np.linalg.norm(a["hip_p"] - a["hip_p_ref"], axis=1)
        ec = np.linalg.norm(a["hip_p"] - a["hip_p_ctrl_ref"], axis=1)
        dyaw = a["hip_yaw"] - a["hip_yaw_ref"]
        T = np.abs(a["T"])
        out.update({
            "hip_com_error_rms_m": _f(np.sqrt(np.mean(e ** 2))),
            "hip_com_error_max_m": _f(e.max()),
            "hip_com_error_vs_controller_reference_rms_m": _f(np.sqrt(np.mean(ec ** 2))),
            "hip_com_error_vs_controller_reference_max_m": _f(ec.max()),
            "hip_yaw_error_rms_rad": _f(np.sqrt(np.mean(dyaw ** 2))),
            "torque_peak_Nm": {name: _f(T[:, i].max()) for i, name in enumerate(T_NAMES)},
            "torque_cmd_peak_Nm": {name: _f(np.abs(a["T_cmd"][:, i]).max()) for i, name in enumerate(T_NAMES)},
            "saturated_fraction": _f(a["saturated"].any(axis=1).mean()),
            "saturated_fraction_per_actuator": {name: _f(a["saturated"][:, i].mean())
                                                for i, name in enumerate(T_NAMES)},
            "constraint_drift_max_m": _f(a["drift_position"].max()),
            "constraint_drift_max_rad": _f(a["drift_orientation"].max()),
        })
    ground = result.extra.get("ground")
    if ground is not None:  # an engine with real contact (MuJoCo): falls and how the feet held on the ground
        out.update({"fell": bool(ground["fell"]), "fall_time_s": ground["fall_time_s"],
                    "fall_reason": ground["fall_reason"], "foot_slip_max_m": _f(ground["foot_slip_max_m"]),
                    "foot_tilt_max_rad": _f(ground["foot_tilt_max_rad"]),
                    "stance_tilt_max_rad": _f(ground["stance_tilt_max_rad"]),
                    "penetration_max_m": _f(ground["penetration_max_m"]),
                    "control_period_s": _f(ground["control_period_s"])})
    td = [p.touchdown_error_m for p in result.phases if p.touchdown_error_m is not None]
    out["toe_touchdown_error_max_m"] = _f(max(td)) if td else None
    out["phase_log"] = [{"phase": p.index + 1, "name": p.name, "start": _f(p.t_start),
                         "end": _f(p.t_end) if p.t_end is not None else None,
                         "nominal_start": _f(p.nominal_start), "nominal_end": _f(p.nominal_end),
                         "touchdown_error_m": p.touchdown_error_m, "landing_tilt_rad": p.landing_tilt_rad}
                        for p in result.phases]
    return out


def contact_audit(result: SimResult, scenario: Any, hm: Any, phase_names: list[str]) -> tuple[dict[str, Any], Any]:
    """The ``contact`` section of summary.json and the :class:`humanoid_sim.audit.AuditReport` behind it (None, and
    ``{"error": message}``, when the log is inconsistent with the phase contact sets)."""
    from humanoid_sim.audit import AuditError, audit_results

    try:
        report = audit_results({**result.log.arrays(), "phase_names": np.array(phase_names)}, hm,
                               scenario.contact.friction_coefficient)
    except AuditError as exc:
        return {"error": str(exc)}, None
    out = report.summary()
    if "landings" in result.extra:   # an engine that welds landing feet: what each touchdown did (landing.py)
        from humanoid_sim.landing import landing_summary

        out["landing"] = landing_summary(result.extra["landings"], scenario.contact.friction_coefficient)
    return out, report


def summarize_with_audit(result: SimResult, scenario: Any, engine: str, hm: Any,
                         phase_names: list[str]) -> dict[str, Any]:
    """:func:`summarize` plus the contact-feasibility audit (:func:`contact_audit`) as its ``contact`` section, as
    ``walk.py`` writes summary.json.  ``scenario``: the :class:`humanoid_sim.scenario.Scenario` run (its name and
    friction coefficient); ``phase_names``: the names of the logged phase indices (``result.phase_names``)."""
    summary = summarize(result, scenario.name, engine)
    summary["contact"] = contact_audit(result, scenario, hm, phase_names)[0]
    return summary
