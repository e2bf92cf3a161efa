"""``walk``: run a scenario, save results and plots, optionally play it in meshcat.

    python scripts/walk.py [SCENARIO] [--out DIR] [--engine pinocchio|thesis|mujoco] [--no-kernel] [--until SECONDS]
                           [--figures quick|all|none] [--no-plots] [--no-html] [--view]

The outputs go to ``results/<scenario name>/<engine>/`` unless ``--out`` says otherwise.  ``--figures`` picks the
figures: the few a user looks at first (``quick``, the default), the thesis's full set (``all``), or none
(``none``, also ``--no-plots``).

Exit status: 0 when the walk completes every planned phase or reaches its ``--until`` time, 1 when it fails or
falls (the reason is printed, the partial results are saved with completed = false) or is stopped by Ctrl-C or
SIGTERM (results.npz and summary.json are written at once, the figures and playback skipped; the live meshcat
server stops too), 2 on bad input (nothing is written).  The first run after an install builds the compiled
kernel's cache (:mod:`humanoid_sim.sim.builds`).  Outputs get the mode a plain ``open()`` gives; the figures and
playback of an earlier run in the output folder are removed before this run writes its own, and the summary lists
what it wrote.
"""

from __future__ import annotations

import argparse
import gc
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from humanoid_sim.engines import ENGINE_NAMES
from humanoid_sim.errors import ControllerError, HumanoidSimError, InputError
from humanoid_sim.paths import SCENARIOS_DIR

if TYPE_CHECKING:  # pragma: no cover
    from humanoid_sim.sim.builds import KernelBuild

DEFAULT_SCENARIO = SCENARIOS_DIR / "sim1.yaml"


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="walk.py", description="Simulate a humanoid walking scenario "
                                "(Akalin 2010 re-implemented on Pinocchio).")
    p.add_argument("scenario", nargs="?", type=Path, default=DEFAULT_SCENARIO,
                   help="scenario YAML (default: scripts/params/sim1.yaml, the thesis's Simulation 1)")
    p.add_argument("--out", type=Path, default=None,
                   help="output folder (default: results/<scenario name>/<engine>/)")
    p.add_argument("--engine", choices=ENGINE_NAMES, default="pinocchio",
                   help="dynamics engine: the fast Pinocchio path (welded feet), "
                        "the thesis's NumPy formulas (slow), or "
                        "MuJoCo (real unilateral, frictional foot contact: would the walk stand?)")
    p.add_argument("--no-kernel", action="store_true",
                   help="run every stage on the NumPy reference path instead of the compiled kernel (about 4x "
                        "slower; to try a change to the controller or dynamics code before porting it to "
                        "its compiled twin, e.g. humanoid_sim/controllers/thesis/compiled.py)")
    p.add_argument("--until", type=float, default=None, metavar="SECONDS",
                   help="stop the simulation at this time (s)")
    p.add_argument("--figures", choices=("quick", "all", "none"), default=None,
                   help="PNG figures to draw: quick (the default: phase timeline, right-leg torques, ground "
                        "reactions, contact audit; about a second), all (the thesis's full set of 27), or none")
    p.add_argument("--no-plots", action="store_true", help="do not write the PNG figures (= --figures none)")
    p.add_argument("--no-html", action="store_true", help="do not write playback.html")
    p.add_argument("--view", action="store_true", help="play the run live in a meshcat server on 127.0.0.1: prints "
                   "the URL, waits for a browser, plays there; Ctrl-C stops the server")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--full-rate", action="store_true",
                   help="also write trace.npz: the signals at every integration step (every MuJoCo step), from which "
                        "the summary's peaks are taken (~1.3 MB per simulated second on MuJoCo)")
    return p


def _fail_input(msg: str) -> int:
    print(f"walk.py: error: {msg}", file=sys.stderr)
    return 2


class Terminated(KeyboardInterrupt):
    """SIGTERM, turned into an interrupt so that the run stops as after Ctrl-C: partial results saved, child
    processes (the meshcat server, the kernel build) stopped."""


def _on_sigterm(signum: int, frame: object) -> None:
    raise Terminated()


def main(argv: list[str] | None = None) -> int:
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():  # signal handlers can only be set there
        previous = signal.signal(signal.SIGTERM, _on_sigterm)
        try:
            return _main(argv)
        finally:
            signal.signal(signal.SIGTERM, previous)
    return _main(argv)


def _main(argv: list[str] | None) -> int:
    args = _parser().parse_args(argv)
    args.command = list(sys.argv) if argv is None else ["walk.py", *argv]
    if args.no_plots and args.figures not in (None, "none"):
        return _fail_input(f"--no-plots contradicts --figures {args.figures}")
    args.figures = "none" if args.no_plots else (args.figures or "quick")
    if args.until is not None and not (args.until > 0):
        return _fail_input(f"--until: expected a positive time in s, got {args.until}")
    # Validate everything before any output is written.
    from humanoid_sim.scenario.schema import ScenarioError, load_scenario

    try:
        scenario = load_scenario(args.scenario)
    except ScenarioError as exc:
        return _fail_input(str(exc))
    out = args.out if args.out is not None else default_out(scenario.name, args.engine)
    if out.exists() and not out.is_dir():
        return _fail_input(f"--out: {out} exists and is not a folder")
    try:
        return _run(args, scenario, out)
    except KeyboardInterrupt as exc:  # outside the simulation loop (which keeps its partial log itself)
        what = "terminated (SIGTERM)" if isinstance(exc, Terminated) else "interrupted"
        print(f"walk.py: {what}; files already written are complete (atomic writes)", file=sys.stderr)
        return 1


def default_out(scenario_name: str, engine: str) -> Path:
    """The output folder of a walk without ``--out``: ``results/<scenario name>/<engine>/``, so that one scenario
    walked on two engines keeps both."""
    return Path("results") / scenario_name / engine


def _build_kernel(args: argparse.Namespace, scenario) -> KernelBuild | None:
    """Start compiling the kernel into numba's disk cache in child processes when this run needs it and the cache
    is missing or stale (:mod:`humanoid_sim.sim.builds`); the running build, or None."""
    import os

    from humanoid_sim import kernel

    if args.engine not in ("pinocchio", "mujoco") or args.no_kernel or not kernel.AVAILABLE:
        return None
    if os.environ.get("HUMANOID_SIM_KERNEL_BUILD", "1") == "0":  # compile in this process, the ordinary way
        if not kernel.cache_present() and not args.quiet:
            print("walk.py: compiling the simulation kernel in this process (HUMANOID_SIM_KERNEL_BUILD=0: up to a "
                  "minute)", file=sys.stderr)
        return None
    from humanoid_sim.sim import builds as build

    parts = build.parts_for(scenario)
    if build.cache_ready(parts):
        return None
    if not args.quiet:
        print("walk.py: compiling the simulation kernel (first run after an install or an edit of "
              "a compiled module; numba caches it for later runs)", file=sys.stderr)
    return build.KernelBuild(args.scenario, parts).start()


def _wait_kernel(running: KernelBuild, quiet: bool) -> None:
    """Wait for a :class:`KernelBuild`, showing its progress; a failed build is reported and left to numba."""
    from humanoid_sim.sim.builds import KernelBuildError

    bar = None
    if not quiet:
        from tqdm import tqdm

        bar = tqdm(total=len(running.parts), bar_format="  kernel: {n}/{total} parts compiled [{elapsed}] {desc}",
                   file=sys.stderr)
    try:
        def done(part: str, elapsed: float) -> None:
            if bar is not None:
                bar.set_description_str(f"{part} done at {elapsed:.1f} s", refresh=False)
                bar.update(1)

        # the elapsed time ticks on a terminal; elsewhere (a log file) only the finished parts are printed
        running.wait(progress=done, tick=(bar.refresh if bar is not None and sys.stderr.isatty() else None))
    except KernelBuildError as exc:
        print(f"walk.py: warning: {exc}; compiling in this process instead (up to a minute)", file=sys.stderr)
    finally:
        if bar is not None:
            bar.close()


def _run(args: argparse.Namespace, scenario, out: Path) -> int:
    """Simulate a validated scenario and write its outputs into ``out``; the exit status.  The processes that draw
    the figures start before the walk simulates, so that they load matplotlib meanwhile on another core
    (:mod:`humanoid_sim.outputs.plots.pool`; stopped once the outputs are written, or here on any exit)."""
    from humanoid_sim.outputs.plots import pool

    try:
        return _walk(args, scenario, out)
    finally:
        pool.stop()


def _walk(args: argparse.Namespace, scenario, out: Path) -> int:
    from humanoid_sim import api
    from humanoid_sim.analysis.summary import provenance
    from humanoid_sim.outputs.plots import pool
    from humanoid_sim.sim.status import RunStatus

    if args.figures != "none":   # forked now, the workers share what this process has loaded so far
        from humanoid_sim.outputs.plots.thesis import FIGURE_SETS, warm_up

        pool.start(len(FIGURE_SETS[args.figures]), warm_up)

    running = _build_kernel(args, scenario)
    try:
        hm = api.robot(scenario.robot)
        if running is not None:
            _wait_kernel(running, args.quiet)
    finally:
        if running is not None:
            running.stop()
    if args.engine == "mujoco" and not args.no_kernel:
        from humanoid_sim.engines.mujoco import compiled as mujoco_compiled
        from humanoid_sim.sim.builds import build_mujoco_reads

        if not mujoco_compiled.cache_ready():   # before the progress bar: it would sit at 0 for ~5 s
            if not args.quiet:
                print("walk.py: compiling the MuJoCo engine's ground reads (first run after an install: ~5 s, "
                      "cached for later runs)", file=sys.stderr)
            build_mujoco_reads(hm, scenario)
    import time

    from humanoid_sim.references.zmp import GaitError

    if scenario.gait.is_zmp and not args.quiet:
        print("walk.py: planning the zmp_preview gait (ZMP preview control and its multibody correction: a few "
              "seconds per 10 s of walk)", file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    try:
        sim = api.prepare(scenario, args.engine, compiled=False if args.no_kernel else None)
    except GaitError as exc:   # the planner cannot make this path's zmp_preview gait
        return _fail_input(f"{scenario.source}: gait.hip_reference: zmp_preview cannot plan this walk: {exc}")
    except InputError as exc:
        return _fail_input(f"{scenario.source}: {exc}")
    if scenario.gait.is_zmp and not args.quiet:
        print(f"walk.py: planned the gait and set up the walk in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    gc.freeze()   # the modules and the set-up stay: the full collections of the walk and its outputs skip them
    t_nominal = sim.traj.phases[-1].t_end
    bar = None
    progress = None
    total = round(args.until if args.until is not None else t_nominal, 2)
    if not args.quiet:
        from tqdm import tqdm

        # no {postfix} (tqdm prefixes it with ", "): the phase goes into {desc}, at the end of the line
        bar = tqdm(total=total, unit="sim s", file=sys.stderr,
                   bar_format="{percentage:3.0f}%|{bar}| {n:.2f}/{total:.2f} sim s [{elapsed}<{remaining}] {desc}")

        def progress(t: float, k: int) -> None:
            now = min(round(t, 2), total)  # never past the total: tqdm would warn and count time backwards
            if now > bar.n:
                bar.update(now - bar.n)
                bar.n = now  # exactly, without the round-off of accumulated increments
            bar.set_description_str(f"phase {k + 1}/{sim.traj.n_phases} {sim.traj.phases[k].name}", refresh=False)

    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return _fail_input(f"--out: cannot create {out}: {exc}")
    result = sim.run(t_end=args.until, progress=progress)
    if bar is not None:
        if result.status.reached_end:  # the walk reached its end: the bar shows it whatever the last step's time
            bar.n = total
            bar.refresh()
        bar.close()
    run = api.finish(sim, result)
    run.summary["provenance"] = provenance(args.command)
    interrupted = result.status is RunStatus.INTERRUPTED   # Ctrl-C: save the log now, skip the slow outputs
    stale = _remove_stale_outputs(out)
    written = run.write(out, figures="none" if interrupted else args.figures,
                        playback=not (args.no_html or interrupted), full_rate=args.full_rate)
    pool.stop()   # the figures are drawn: no idle workers while the summary prints or the live view plays
    figures = [p for p in written if p.suffix == ".png"]
    html = next((p for p in written if p.suffix == ".html"), None)
    _print_summary(run.summary, out)
    _print_outputs(args, out, figures, html, stale, len(result.log), interrupted)
    if args.view and len(result.log) and not interrupted:
        from humanoid_sim.outputs.viewer import play_live

        play_live(out / "results.npz", hm=hm, traj=sim.traj)
    status = result.status
    if status is RunStatus.INTERRUPTED:
        print(f"walk.py: {result.reason}; results.npz and summary.json written, figures and playback skipped "
              f"(draw them with: python scripts/plot.py {out / 'results.npz'})", file=sys.stderr)
        return 1
    if not status.reached_end:
        print(f"walk.py: {'the robot fell' if status is RunStatus.FELL else 'run failed'}: {result.reason}",
              file=sys.stderr)
        if _raised_elsewhere(result.error):
            print(result.traceback.rstrip(), file=sys.stderr)
        return 1
    return 0


def _raised_elsewhere(error: BaseException | None) -> bool:
    """Whether the error that ended a run came from code outside the simulator's own checks (a controller's
    exception, or an unexpected error): its traceback then shows the file and line that raised."""
    if error is None:
        return False
    if isinstance(error, ControllerError):
        return error.__cause__ is not None
    return not isinstance(error, HumanoidSimError)


def output_names() -> list[str]:
    """Every file name walk.py may write into its output folder besides results.npz and summary.json: figures,
    figures of earlier versions, playback.html, the design files and trace.npz."""
    from humanoid_sim.outputs.design import SIZING_FIGURES
    from humanoid_sim.outputs.plots.thesis import FIGURES, LEGACY_STEMS

    return ([f"{stem}.png" for stem in FIGURES + LEGACY_STEMS + tuple(SIZING_FIGURES)]
            + ["playback.html", "trace.npz", "design.csv", "fatigue.csv", "load_cases.json"])


def _remove_stale_outputs(out: Path) -> list[str]:
    """Remove the figures and playback an earlier run left in ``out`` (only walk.py's own file names), so that none
    passes for this run's; the names removed.  This run then writes its own."""
    removed = []
    for name in output_names():
        path = out / name
        if path.is_file():
            path.unlink()
            removed.append(name)
    return removed


def _print_outputs(args: argparse.Namespace, out: Path, figures: list[Path], html: Path | None, stale: list[str],
                   steps: int, interrupted: bool = False) -> None:
    written = {p.name for p in figures} | ({html.name} if html is not None else set()) | \
        {name for name in ("design.csv", "fatigue.csv", "load_cases.json", "trace.npz") if (out / name).is_file()}
    design = (out / "design.csv").is_file()
    parts = ["results.npz", "summary.json", "design.csv, fatigue.csv, load_cases.json" if design else
             "no design files (no step)"]
    if (out / "trace.npz").is_file():
        parts.append("trace.npz")
    if figures:
        parts.append(f"{len(figures)} figures (*.png" + (", --figures all for the full set" if args.figures == "quick"
                                                         else "") + ")")
    else:
        parts.append("no figures (" + ("--no-plots" if args.no_plots else "--figures none" if args.figures == "none"
                                       else "the run ended before its first step: nothing to plot" if not steps
                                       else "interrupted" if interrupted else "the contact audit failed") + ")")
    parts.append("playback.html" if html is not None else
                 "no playback.html (" + ("--no-html" if args.no_html else "nothing to play" if not steps else
                                         "interrupted" if interrupted else "meshcat missing") + ")")
    print(f"  outputs in {out}/: " + ", ".join(parts))
    gone = sorted(set(stale) - written)
    if gone:
        print(f"  removed {len(gone)} outputs of an earlier run that this run did not write: "
              + ", ".join(gone[:4]) + (", ..." if len(gone) > 4 else ""))


FEASIBLE_WALK = "python scripts/walk.py scripts/params/sim1_zmp.yaml --engine mujoco"
"""The command the console points to when a walk's contacts are infeasible."""


def status_line(s: dict) -> str:
    """The console's first line about a run: what ran, on which engine, and how it ended (completed, stopped at the
    requested time, interrupted, fell, failed)."""
    what = f"{s['scenario']} on {s['engine']} ({'real contact' if 'fell' in s else 'welded feet'})"
    status = s["status"]
    if status == "completed":
        return f"{what}: completed -- {s['reason']}"
    if status == "stopped":
        return f"{what}: stopped at t = {s['sim_time_s']:.3f} s (requested)"
    if status == "interrupted":
        return f"{what}: INTERRUPTED (stopped on request: Ctrl-C or SIGTERM) -- {s['reason']}"
    return f"{what}: {status.upper()} -- {s['reason']}"


def _mm(x: float | None) -> str:
    return "n/a" if x is None else f"{1000 * x:.1f} mm"


def _print_summary(s: dict, out: Path) -> None:
    real = "fell" in s   # an engine with real, unilateral contact (MuJoCo) reports falls, slip, tilt, penetration
    if s.get("feasible") is False and not real:
        print(f"INFEASIBLE CONTACTS: {s['feasibility_reason']}. Real ground could not carry this walk, so its torques "
              f"are not a design load. The feasible walk: {FEASIBLE_WALK}")
    print(status_line(s))
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
        print(f"  peak torque {peak[0]} {peak[1]:.1f} N m; saturated {100 * s['saturated_fraction']:.1f} % of steps"
              + ("" if real else f"; weld drift max {s['constraint_drift_max_m']:.2e} m"))
    if real:
        tilt = s["stance_tilt_max_rad"]
        print("  on the ground: " + (f"FELL at t = {s['fall_time_s']:.3f} s" if s["fell"] else "stood")
              + f"; foot slip max {_mm(s['foot_slip_max_m'])}; stance foot tilt max "
              + ("n/a" if tilt is None else f"{tilt:.3f} rad") + f"; penetration max {_mm(s['penetration_max_m'])}")
    d = s.get("design")
    if d is not None:
        w, b = d["walk"], d["walk"]["binding_joint"]
        cot = w["mechanical_cost_of_transport"]
        rate = d["rates"]["trace_period_s"]
        print(f"  design (every {rate * 1000:g} ms step"
              + (f", after {d['rates']['settling_excluded_s']:g} s of settling" if d["rates"]["settling_excluded_s"]
                 else "") + f"): {w['distance_m']:.2f} m walked, positive joint work {w['work_positive_J']:.0f} J, "
              f"mechanical cost of transport {'n/a' if cot is None else f'{cot:.2f}'}; peak vertical ground force "
              + ("n/a" if w["ground_force_vertical_peak_N"] is None else f"{w['ground_force_vertical_peak_N']:.0f} N")
              + ("" if b is None else f"; tightest joint {b['joint']} at {b['torque_peak_Nm']:.1f} of "
                 f"{b['limit_Nm']:g} N m") + " (design.csv)")
    m = (d or {}).get("actuators")
    if m is not None:
        cot = m["electrical_cost_of_transport"]
        hot = max(m["joints"].items(), key=lambda kv: kv[1]["peak_winding_temperature_C"], default=None)
        print(f"  motors on {len(m['joints'])} joints: electrical energy {m['electrical_energy_drawn_J']:.0f} J drawn, "
              f"electrical cost of transport {'n/a' if cot is None else f'{cot:.2f}'}"
              + ("" if hot is None else f"; hottest winding {hot[0]} {hot[1]['peak_winding_temperature_C']:.1f} C"))
        for sf in m["envelope_shortfalls"]:
            print(f"  MOTOR SHORT: {sf['joint']} ({sf['motor']}) could not give the torque asked in "
                  f"{sf['clipped_calls']} controller calls from t = {sf['first_s']:.3f} s to {sf['last_s']:.3f} s, "
                  f"worst by {sf['worst_shortfall_Nm']:.1f} N m at t = {sf['worst_at_s']:.3f} s")
        for fail in m["failing"]:
            print(f"  MOTOR FAILS: {fail}")
    c = s.get("contact", {})
    if "error" in c:
        print(f"  contact audit failed: {c['error']}")
    elif c.get("steps"):
        pct = lambda x: "n/a" if x is None else f"{100 * x:.0f} %"  # noqa: E731
        fmin = ", ".join(f"{k} {v:.0f} N" for k, v in c["min_normal_force_N"].items() if v is not None)
        head = (f"contact forces of real unilateral contact ({s['engine']})" if real else
                "contact feasibility of the welded feet")
        print(f"  {head} (mu {c['friction_coefficient']:g}): min normal force {fmin}; CoP outside "
              f"the sole R {pct(c['cop_outside_fraction']['R'])} / L {pct(c['cop_outside_fraction']['L'])}; "
              f"friction exceeded R {pct(c['friction_exceeded_fraction']['R'])} / "
              f"L {pct(c['friction_exceeded_fraction']['L'])}; ZMP outside {pct(c['zmp_outside_fraction'])}")


if __name__ == "__main__":
    sys.exit(main())
