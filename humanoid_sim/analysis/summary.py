"""summary.json: the numbers a user reads first after a run (tracking, torques, contacts, speed)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from humanoid_sim.robot.actuators import T_NAMES
from humanoid_sim.sim.simulate import SimResult
from humanoid_sim.sim.status import RunStatus


def _f(x: Any) -> float | None:
    x = float(x)
    return x if np.isfinite(x) else None


def summarize(result: SimResult, scenario_name: str, engine: str) -> dict[str, Any]:
    """Summary of a run (SI units: m, rad, N m, s).  Runs on an engine with real contact (``--engine mujoco``) add
    ``fell``, ``fall_time_s``, ``fall_reason``, ``foot_slip_max_m``, ``foot_tilt_max_rad``, ``penetration_max_m``
    and ``control_period_s`` (:meth:`humanoid_sim.engines.mujoco.engine.MujocoEngine.run_info`)."""
    a = result.log.arrays()
    n = len(result.log)
    out: dict[str, Any] = {
        "scenario": scenario_name,
        "engine": engine,
        "completed": bool(result.completed),
        "status": result.status.value,
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
        tr = result.trace.columns if result.trace is not None else a   # torques at every integration step
        T = np.abs(tr["T"])
        out.update({
            "hip_com_error_rms_m": _f(np.sqrt(np.mean(e ** 2))),
            "hip_com_error_max_m": _f(e.max()),
            "hip_com_error_vs_controller_reference_rms_m": _f(np.sqrt(np.mean(ec ** 2))),
            "hip_com_error_vs_controller_reference_max_m": _f(ec.max()),
            "hip_yaw_error_rms_rad": _f(np.sqrt(np.mean(dyaw ** 2))),
            "torque_peak_Nm": {name: _f(T[:, i].max()) for i, name in enumerate(T_NAMES)},
            "torque_cmd_peak_Nm": {name: _f(np.abs(tr["T_cmd"][:, i]).max()) for i, name in enumerate(T_NAMES)},
            "saturated_fraction": _f(tr["saturated"].any(axis=1).mean()),
            "saturated_fraction_per_actuator": {name: _f(tr["saturated"][:, i].mean())
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
    if "disturbances" in result.extra:   # a scenario's pushes, terrain and sensing as applied (sim/disturbances.py)
        out["disturbances"] = result.extra["disturbances"]
    td = [p.touchdown_error_m for p in result.phases if p.touchdown_error_m is not None]
    out["toe_touchdown_error_max_m"] = _f(max(td)) if td else None
    out["phase_log"] = [{"phase": p.index + 1, "name": p.name, "start": _f(p.t_start),
                         "end": _f(p.t_end) if p.t_end is not None else None,
                         "nominal_start": _f(p.nominal_start), "nominal_end": _f(p.nominal_end),
                         "touchdown_error_m": p.touchdown_error_m, "landing_tilt_rad": p.landing_tilt_rad}
                        for p in result.phases]
    return out


def contact_audit(result: SimResult, scenario: Any, hm: Any, phase_names: list[str]) -> tuple[dict[str, Any], Any]:
    """The ``contact`` section of summary.json and the :class:`humanoid_sim.analysis.audit.AuditReport` of the log's
    steps for the figures (None, and ``{"error": message}``, when the log is inconsistent with the phase contact
    sets).  The section judges every integration step (the full-rate trace, when the engine records one: its
    ``rate`` says which); on real ground each foot's polygon is the hull of both sole parts
    (:func:`humanoid_sim.analysis.audit.audit_results`, ``real_ground``).

    The section is :meth:`humanoid_sim.analysis.audit.AuditReport.summary` (its fractions judge edges with
    :data:`EDGE_VERDICT_TOL_M` and skip the unloaded steps), plus what the engine measured on the ground: ``landing``
    (an engine that welds landing feet: :func:`humanoid_sim.engines.landing.landing_summary`), and on real ground
    ``settling`` and ``sliding`` when the engine's ``run_info`` gives them in its ``ground`` entry
    (:meth:`humanoid_sim.engines.mujoco.ground.GroundMeter.report`: the start-up settling's measures, the feet's
    sliding events)."""
    from humanoid_sim.analysis.audit import AuditError, audit_results

    real_ground = "ground" in result.extra   # an engine with real contact (MuJoCo) reports its ground measures
    mu = scenario.contact.friction_coefficient
    try:
        report = audit_results({**result.log.arrays(), "phase_names": np.array(phase_names)}, hm, mu, real_ground)
        full = report
        trace = result.trace
        if trace is not None and trace.source == "engine" and len(trace) and \
                result.status is not RunStatus.INTERRUPTED:   # the section over every step (not after Ctrl-C)
            full = audit_results({**trace.columns, "phase_names": np.array(phase_names)}, hm, mu, real_ground)
    except AuditError as exc:
        return {"error": str(exc)}, None
    if real_ground:   # soft ground: contacts act below z = 0, which moves their CoP on z = 0 (real_ground_edge_tol)
        tol = real_ground_edge_tol(mu, result.extra["ground"])
        same = full is report      # no full-rate trace (a run stopped at its first step, or interrupted)
        report = replace(report, edge_tol=tol)
        full = report if same else replace(full, edge_tol=tol)
    out = full.summary()
    out["rate"] = {"period_s": trace.period_s if full is not report else None,
                   "rows": len(full.t), "source": "full-rate trace" if full is not report else "log"}
    if "landings" in result.extra:   # an engine that welds landing feet: what each touchdown did (landing.py)
        from humanoid_sim.engines.landing import landing_summary

        out["landing"] = landing_summary(result.extra["landings"], scenario.contact.friction_coefficient)
    ground = result.extra.get("ground") or {}
    for key in ("settling", "sliding"):     # real ground (engines/mujoco/ground.py)
        if key in ground:
            out[key] = ground[key]
    return out, report


def real_ground_edge_tol(mu: float, ground: dict[str, Any]) -> float:
    """The edge tolerance of the audit on soft (MuJoCo's) ground, m: :data:`EDGE_VERDICT_TOL_M` plus mu times the
    run's deepest penetration.  A foot's centre of pressure is defined on the plane z = 0, while soft ground's contact
    forces act at their contact points up to the penetration depth p below it; a force whose tangential part is r
    times its normal part (r <= mu inside the cone) then puts that CoP r p from its contact point, outside the sole's
    footprint when the contact is on an edge.  Measured: a trailing toe sliding at r = 0.72 during a 4.2 mm
    penetration on sim1_zmp put its CoP 1.4 mm past the edge."""
    depth = max(float(ground.get("penetration_max_m") or 0.0),
                float((ground.get("settling") or {}).get("penetration_max_m") or 0.0))
    return EDGE_VERDICT_TOL_M + mu * depth


def summarize_with_audit(result: SimResult, scenario: Any, engine: str, hm: Any,
                         phase_names: list[str]) -> dict[str, Any]:
    """:func:`summary_and_audit`'s summary: what ``walk.py`` writes as summary.json."""
    return summary_and_audit(result, scenario, engine, hm, phase_names)[0]


def summary_and_audit(result: SimResult, scenario: Any, engine: str, hm: Any,
                      phase_names: list[str]) -> tuple[dict[str, Any], Any]:
    """:func:`summarize` plus the contact-feasibility audit (:func:`contact_audit`) as its ``contact`` section and
    the :func:`feasibility` verdict, and the audit's report (for the figures; None when the audit failed).

    Args:
        result: the run.
        scenario: the :class:`humanoid_sim.scenario.schema.Scenario` run (its name and friction coefficient).
        engine: the engine's name.
        hm: the robot model.
        phase_names: the names of the logged phase indices (``result.phase_names``).
    """
    return summary_audit_design(result, scenario, engine, hm, phase_names)[:2]


def summary_audit_design(result: SimResult, scenario: Any, engine: str, hm: Any,
                         phase_names: list[str]) -> tuple[dict[str, Any], Any, Any]:
    """:func:`summary_and_audit` plus the design numbers (:func:`humanoid_sim.analysis.design.design_card`) as the
    summary's ``design`` section; returns (summary, audit report, design card: None without a logged step or after
    Ctrl-C, which answers at once).  On an engine with real contact the start-up settling is left out of the design
    numbers and reported apart."""
    from humanoid_sim.analysis.design import design_card

    summary = summarize(result, scenario.name, engine)
    summary["contact"], report = contact_audit(result, scenario, hm, phase_names)
    summary.update(feasibility(summary))
    card = None
    # a run stopped by Ctrl-C answers at once (the card takes a moment); a run without a logged step has no walk
    if result.trace is not None and len(result.trace) and len(result.log) and result.status is not \
            RunStatus.INTERRUPTED:
        # an engine with real contact starts by settling on it: the walk's numbers start after that window
        settling = result.extra.get("ground", {}).get("settling", {}).get("window_s", 0.0)
        motors = scenario.actuators.motors if getattr(scenario, "actuators", None) is not None else None
        drive = result.extra.get("actuators") or {}
        card = design_card(result.trace, result.log.arrays(), hm, settling, motors,
                           drive.get("envelope_shortfalls"))
        summary["design"] = card.summary()
    if getattr(scenario, "robot", None) is not None:
        summary["robot"] = robot_section(scenario.robot, hm)
    return summary, report, card


def robot_section(variant: Any, hm: Any) -> dict[str, Any]:
    """The summary's ``robot`` entry of a scenario with a ``robot:`` section: the generated model's mass (kg,
    Pinocchio's sum over its bodies, rotors excluded), its URDF file and hash, and the variant's parameters."""
    mass = float(sum(inertia.mass for inertia in hm.model.inertias))
    return {"mass_kg": mass, "model": Path(hm.urdf_path).name,
            "nominal": bool(variant.is_nominal), "parameters": variant.parameters()}


from humanoid_sim.analysis.audit import EDGE_TOL_M  # noqa: E402  (imported here, with the verdict that reads it)

EDGE_VERDICT_TOL_M = EDGE_TOL_M
"""m: a centre of pressure up to this far outside its sole's edge still counts as on the sole, in the feasibility
verdict and in the audit's fractions: the one edge tolerance, :data:`humanoid_sim.analysis.audit.EDGE_TOL_M` (1 mm;
its docstring gives the measurements). A foot pivoting on an edge of MuJoCo's soft ground puts its CoP just past
the edge (3-25 um measured); a walk that needs ground beyond its soles misses by centimetres."""


def feasibility(summary: dict[str, Any]) -> dict[str, Any]:
    """The verdict on whether real ground could carry the walk: ``{"feasible": bool, "feasibility_reason": str}``.

    On an engine with real contact (MuJoCo) the ground is physical, so the walk is feasible unless it fell. On the
    welded engines it is feasible when no foot pulls on the ground, no centre of pressure lies more than
    :data:`EDGE_VERDICT_TOL_M` outside its sole (the tolerance the audit's ``cop_outside_fraction`` counts with,
    so the percentage quoted is that of the steps beyond it), and no foot needs more friction than the scenario's
    coefficient; the audit's unloaded steps are judged by none of these.

    Args:
        summary: a run's summary with its ``contact`` section (:func:`contact_audit`).
    """
    if "fell" in summary:
        if summary["fell"]:
            return {"feasible": False, "feasibility_reason": f"fell on real ground: {summary['fall_reason']}"}
        return {"feasible": True, "feasibility_reason": "stood on real (unilateral, frictional) ground"}
    c = summary.get("contact", {})
    if "error" in c or not c.get("steps"):
        return {"feasible": None, "feasibility_reason": "no contact audit: " + c.get("error", "no logged step")}
    problems = []
    for foot in ("R", "L"):
        pull, fric = c["pulling_fraction"][foot], c["friction_exceeded_fraction"][foot]
        margin, outside = c["min_cop_margin_m"][foot], c["cop_outside_fraction"][foot]
        if pull:
            problems.append(f"foot {foot} pulls on the ground in {100 * pull:.0f} % of its contact steps")
        if margin is not None and margin < -EDGE_VERDICT_TOL_M:
            problems.append(f"foot {foot}'s centre of pressure lies outside its sole in {100 * outside:.0f} % of its "
                            f"contact steps (up to {-1000 * margin:.0f} mm)")
        if fric:
            problems.append(f"foot {foot} needs more friction than mu = {c['friction_coefficient']:g} in "
                            f"{100 * fric:.0f} % of its contact steps")
    if problems:
        return {"feasible": False, "feasibility_reason": "; ".join(problems)}
    return {"feasible": True, "feasibility_reason": "every ground reaction inside its sole and friction cone"}


PROVENANCE_PACKAGES = ("pin", "mujoco", "numpy", "numba", "scipy")
"""The distributions whose versions ``provenance`` records (``pin`` is Pinocchio's)."""


def git_commit(folder: Any = None) -> str | None:
    """The commit checked out where ``folder`` lies (default: the humanoid_sim package's folder), by
    ``git rev-parse HEAD``; None when it is not a git checkout, git is missing, or git fails in any way."""
    import subprocess

    from humanoid_sim.paths import PACKAGE_DIR

    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=folder or PACKAGE_DIR, capture_output=True, text=True,
                             timeout=5, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    commit = out.stdout.strip()
    return commit if out.returncode == 0 and len(commit) >= 40 else None


def provenance(command: list[str] | str) -> dict[str, Any]:
    """The ``provenance`` section of summary.json: what made the run.

    Keys: ``version`` (humanoid_sim's), ``git_commit`` (:func:`git_commit`, or None), ``packages`` (the version of
    each of :data:`PROVENANCE_PACKAGES`, None where not installed), ``date`` (ISO 8601, UTC, to the second) and
    ``command`` (the command line as a list of words, or a string such as ``"python API: run_walk('sim1')"``).
    """
    import datetime
    import sys
    from importlib import metadata

    package = sys.modules["humanoid_sim"]   # loaded with this module (a static import would reach the API layer)

    def version(dist: str) -> str | None:
        try:
            return metadata.version(dist)
        except metadata.PackageNotFoundError:
            return None

    return {
        "version": package.__version__,
        "git_commit": git_commit(),
        "packages": {name: version(name) for name in PROVENANCE_PACKAGES},
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "command": list(command) if not isinstance(command, str) else command,
    }
