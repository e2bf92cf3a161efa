"""``walk``: run a scenario, save results and plots, optionally play it in meshcat.

    python scripts/walk.py [SCENARIO] [--out DIR] [--engine pinocchio|thesis] [--no-kernel] [--until SECONDS]
                           [--no-plots] [--no-html] [--view]

Exit status: 0 when the walk completes every planned phase, 1 when it fails (the reason is printed, the
partial results are saved with completed = false), 2 on bad input (nothing is written).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


from humanoid_sim import PACKAGE_DIR
from humanoid_sim.engines import ENGINE_NAMES

DEFAULT_SCENARIO = PACKAGE_DIR.parent / "scripts" / "params" / "sim1.yaml"


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="walk.py", description="Simulate a humanoid walking scenario "
                                "(Akalin 2010 re-implemented on Pinocchio).")
    p.add_argument("scenario", nargs="?", type=Path, default=DEFAULT_SCENARIO,
                   help="scenario YAML (default: scripts/params/sim1.yaml, the thesis's Simulation 1)")
    p.add_argument("--out", type=Path, default=None, help="output folder (default: results/<scenario name>/)")
    p.add_argument("--engine", choices=ENGINE_NAMES, default="pinocchio",
                   help="dynamics engine: the fast Pinocchio path or the thesis's NumPy formulas (slow)")
    p.add_argument("--no-kernel", action="store_true",
                   help="run every stage on the NumPy reference path instead of the compiled kernel (about 4x "
                        "slower; to try a change to the controller or dynamics code before porting it to "
                        "humanoid_sim/kernel/compiled.py)")
    p.add_argument("--until", type=float, default=None, metavar="SECONDS",
                   help="stop the simulation at this time (s)")
    p.add_argument("--no-plots", action="store_true", help="do not write the PNG figures")
    p.add_argument("--no-html", action="store_true", help="do not write playback.html")
    p.add_argument("--view", action="store_true", help="play the run live in a meshcat server on 127.0.0.1")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def _fail_input(msg: str) -> int:
    print(f"walk.py: error: {msg}", file=sys.stderr)
    return 2


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    if args.until is not None and not (args.until > 0):
        return _fail_input(f"--until: expected a positive time in s, got {args.until}")
    # Validate everything before any output is written.
    from humanoid_sim.scenario import ScenarioError, load_scenario

    try:
        scenario = load_scenario(args.scenario)
    except ScenarioError as exc:
        return _fail_input(str(exc))
    out = args.out if args.out is not None else Path("results") / scenario.name
    if out.exists() and not out.is_dir():
        return _fail_input(f"--out: {out} exists and is not a folder")
    try:
        return _run(args, scenario, out)
    except KeyboardInterrupt:  # outside the simulation loop (which keeps its partial log itself)
        print("walk.py: interrupted; files already written are complete (atomic writes)", file=sys.stderr)
        return 1


def _run(args: argparse.Namespace, scenario, out: Path) -> int:
    """Simulate a validated scenario and write its outputs into ``out``; the exit status."""
    from humanoid_sim.model import load_model
    from humanoid_sim.results import atomic_write_text
    from humanoid_sim.simulate import Simulator
    from humanoid_sim.summary import contact_audit, summarize

    hm = load_model()
    if args.engine == "pinocchio" and scenario.controller_class is None:
        from humanoid_sim import kernel

        if not args.no_kernel and kernel.AVAILABLE and not kernel.cache_present() and not args.quiet:
            print("walk.py: compiling the simulation kernel (first run after an install or an edit of "
                  "humanoid_sim/kernel/compiled.py: up to a minute, cached for later runs)", file=sys.stderr)
    from humanoid_sim.controllers.loading import ControllerLoadError

    try:
        sim = Simulator(hm, scenario, compiled=False if args.no_kernel else None, engine=args.engine)
    except ControllerLoadError as exc:
        return _fail_input(f"{scenario.source}: {exc}")
    t_nominal = sim.traj.phases[-1].t_end
    bar = None
    progress = None
    if not args.quiet:
        from tqdm import tqdm

        total = args.until if args.until is not None else t_nominal
        bar = tqdm(total=round(total, 2), unit="sim s", bar_format="{l_bar}{bar}| {n:.2f}/{total:.2f} sim s "
                   "[{elapsed}<{remaining}] {postfix}", file=sys.stderr)
        state = {"last": 0.0}

        def progress(t: float, k: int) -> None:
            now = round(min(t, total), 2)
            if now > state["last"]:
                bar.update(round(now - state["last"], 2))
                state["last"] = now
            bar.set_postfix_str(f"phase {k + 1}/{sim.traj.n_phases} {sim.traj.phases[k].name}", refresh=False)

    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return _fail_input(f"--out: cannot create {out}: {exc}")
    result = sim.run(t_end=args.until, progress=progress)
    if bar is not None:
        bar.close()
    phase_names = [p.name for p in sim.traj.phases]
    result.log.save(out / "results.npz", phase_names)
    summary = summarize(result, scenario.name, args.engine)
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=2) + "\n")  # rewritten with the audit
    # contact-feasibility audit (humanoid_sim/audit.py): the "contact" section of summary.json
    summary["contact"], report = contact_audit(result, scenario, hm, phase_names)
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=2) + "\n")
    if not args.no_plots and report is not None and len(result.log):
        from humanoid_sim.plots_audit import plot_contact_audit

        plot_contact_audit(report, out / "contact_audit.png", title=scenario.name)
    if not args.no_plots and len(result.log):
        from humanoid_sim.plots import plot_all

        plot_all(out / "results.npz", out, traj=sim.traj)
    if not args.no_html and len(result.log):
        try:
            from humanoid_sim.viewer import write_playback
        except ImportError:
            write_playback = None
        if write_playback is not None:
            write_playback(out / "results.npz", out / "playback.html", hm=hm, traj=sim.traj)
    _print_summary(summary, out)
    if args.view and len(result.log):
        from humanoid_sim.viewer import play_live

        play_live(out / "results.npz", hm=hm, traj=sim.traj)
    until_ok = args.until is not None and result.reason.startswith("stopped at")
    if not (result.completed or until_ok):
        print(f"walk.py: run failed: {result.reason}", file=sys.stderr)
        return 1
    return 0


def _print_summary(s: dict, out: Path) -> None:
    status = "completed" if s["completed"] else (
        "stopped" if s["reason"].startswith("stopped at") else "FAILED")
    print(f"{s['scenario']}: {status} -- {s['reason']}")
    print(f"  phases {s['phases_completed']}/{s['phases_planned']}, sim {s['sim_time_s']:.2f} s in "
          f"{s['wall_time_s']:.2f} s wall (real-time factor {s['real_time_factor']:.1f}"
          + (f", {s['compiled_stages']} of {s['compiled_stages'] + s['reference_stages']} stages compiled)"
             if "compiled_stages" in s else ")"))
    if "hip_com_error_rms_m" in s:
        peak = max(s["torque_peak_Nm"].items(), key=lambda kv: kv[1] or 0.0)
        td = s["toe_touchdown_error_max_m"]
        print(f"  hip CoM error rms {s['hip_com_error_rms_m'] * 1000:.1f} mm, max "
              f"{s['hip_com_error_max_m'] * 1000:.1f} mm; hip yaw error rms {s['hip_yaw_error_rms_rad']:.3f} rad")
        print(f"  touchdown error max {td * 1000:.1f} mm" if td is not None else "  no touchdown")
        print(f"  peak torque {peak[0]} {peak[1]:.1f} N m; saturated {100 * s['saturated_fraction']:.1f} % of "
              f"steps; weld drift max {s['constraint_drift_max_m']:.2e} m")
    c = s.get("contact", {})
    if "error" in c:
        print(f"  contact audit failed: {c['error']}")
    elif c.get("steps"):
        pct = lambda x: "n/a" if x is None else f"{100 * x:.0f} %"  # noqa: E731
        fmin = ", ".join(f"{k} {v:.0f} N" for k, v in c["min_normal_force_N"].items() if v is not None)
        print(f"  contact feasibility (mu {c['friction_coefficient']:g}): min normal force {fmin}; CoP outside "
              f"the sole R {pct(c['cop_outside_fraction']['R'])} / L {pct(c['cop_outside_fraction']['L'])}; "
              f"friction exceeded R {pct(c['friction_exceeded_fraction']['R'])} / "
              f"L {pct(c['friction_exceeded_fraction']['L'])}; ZMP outside {pct(c['zmp_outside_fraction'])}")
    print(f"  results in {out}/")


if __name__ == "__main__":
    sys.exit(main())
