"""Fill numba's disk cache of the compiled kernel quickly: the first run after an install (or after an edit of any
compiled module, :data:`humanoid_sim.jit.COMPILED_SOURCES`) builds it in two child processes in parallel instead of
compiling in the walk's own process (timings: ``docs/notes/2026-11-26-kernel.md``).

Where the time of a cold compile goes: numba's own front end (typing, lowering) and, most of it, LLVM: function
passes, the whole-module optimisation of every compiled function's library and machine code.

- numba gives every ``@njit`` function its own library and links each callee's code into its caller's library, where
  the whole-module optimisation runs again: a helper five calls deep is optimised five times; and it generates
  machine code for every library as soon as it is compiled (each array expression and library overload has one too:
  ~150 libraries for ``ssp_stage``), although a callee's code only ever runs linked into the entry points
  (:data:`ENTRY_POINTS`, the functions Python calls).

So the children here (``python -m humanoid_sim.sim.builds PART SCENARIO``):

- skip the whole-module optimisation and the machine code of every library that is not an entry point: a callee
  keeps its function-optimised LLVM IR, which its callers link, and goes to the cache as bitcode (a process that
  calls it from Python has numba compile that to machine code on loading).  The entry points are optimised and
  compiled in full with every callee linked in.  Optimisation levels and inlining decide which instructions evaluate
  a formula, not its IEEE arithmetic (numba's code is compiled without fast-math, so LLVM neither reassociates nor
  contracts): the walks are bit for bit those of a kernel compiled the ordinary way (``tests/cli/test_walk.py``,
  ``tests/kernel/test_kernel.py``), and as fast;
- compile nothing twice: :data:`PLAN` splits the work in halves (``ssp``: ``ssp_stage``, the projection and the
  advance; ``dsp``: first ``ssp_dynamics``, the computed-torque half of ``ssp_stage``, then ``dsp_stage``), and a lock
  file per (function, signature) makes a child that needs a callee the other one is compiling wait for it and load it
  from the cache (without the locks both compiled the helpers they share);
- run nothing: each entry point is compiled for the argument types of a representative call (as numba types a call
  from Python).

numba's slice assignment compiles the formatting of its shape-mismatch message and its checks at every site: the
compiled modules copy into slices by loops (``kernel.linalg.put``) instead.  The parent process then loads the
cache.  If numba lacks the internals used here, the children compile the ordinary way (slower, same bits).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from humanoid_sim.errors import HumanoidSimError

ENTRY_POINTS = ("ssp_stage", "dsp_stage", "project_on_support", "advance_on_support", "balance_stage",
                "balance_finish")
"""The compiled functions a walk calls from Python (``StageKernel.stage`` / ``project`` / ``advance``, the balance
controller's ``_qp_compiled`` / ``_finish``)."""
PLAN = {"ssp": ("ssp_stage", "project_on_support", "advance_on_support"), "dsp": ("ssp_dynamics", "dsp_stage"),
        "support": ("project_on_support", "advance_on_support"), "balance": ("balance_stage", "balance_finish")}
"""What each child process of :func:`build` compiles, in order: the entry points and, first in ``dsp``, the computed
torque half of ``ssp_stage`` (which the ``ssp`` child then loads from the cache instead of compiling it too).
``support`` and ``balance`` are the kernel of a walk driven by the balance controller (the zmp gait's default),
which needs neither of the thesis controller's stages."""
PARTS = ("ssp", "dsp")
"""Child processes of :func:`build` for the thesis controller, one per core of the development machine."""
BALANCE_PARTS = ("support", "balance")
"""Child processes of :func:`build` for the balance controller."""


def parts_for(scenario: Any) -> tuple[str, ...]:
    """The parts a walk of ``scenario`` (a parsed :class:`humanoid_sim.scenario.schema.Scenario`) calls: the balance
    controller's when its gait is zmp_preview with the default executor and no controller of the user's."""
    gait = scenario.gait
    if scenario.controller_class is None and gait.is_zmp and gait.controller == "balance":
        return BALANCE_PARTS
    return PARTS
LOCKS_ENV = "HUMANOID_SIM_KERNEL_LOCKS"
"""Environment variable naming the folder of the children's per-function lock files (set by :class:`KernelBuild`)."""
KEEP_MACHINE_CODE = ENTRY_POINTS + ("nrt", "multi3")
"""Libraries the children generate machine code for: the entry points and numba's runtime helpers (which the entry
points call by address)."""
NUMBA_OPT = "2"
"""LLVM optimisation level of the children (numba's default is 3; level 2 runs the walk as fast, measured)."""


class KernelBuildError(HumanoidSimError, RuntimeError):
    """A child process failed to compile its part of the kernel (the message carries its stderr)."""


COMPILED_MODULES = ("humanoid_sim.kernel.linalg", "humanoid_sim.kernel.kinematics", "humanoid_sim.kernel.contact",
                    "humanoid_sim.kernel.actuators", "humanoid_sim.kernel.log", "humanoid_sim.kernel.projection",
                    "humanoid_sim.references.chapter3.compiled", "humanoid_sim.controllers.thesis.compiled",
                    "humanoid_sim.controllers.balance.compiled")
"""The modules whose compiled functions the children compile (the MuJoCo engine's are built by
``engines.mujoco.compiled.build``)."""
_THESIS = "humanoid_sim.controllers.thesis.compiled"
_BALANCE = "humanoid_sim.controllers.balance.compiled"
_PROJECTION = "humanoid_sim.kernel.projection"
HOME = {"ssp_stage": _THESIS, "ssp_dynamics": _THESIS, "dsp_stage": _THESIS, "project_on_support": _PROJECTION,
        "advance_on_support": _PROJECTION, "balance_stage": _BALANCE, "balance_finish": _BALANCE}
"""The module defining each function of :data:`PLAN`."""
_THESIS_STAGE, _SUPPORT = "humanoid_sim.controllers.thesis.stage", "humanoid_sim.kernel.support"
CALLERS = {"ssp_stage": _THESIS_STAGE, "ssp_dynamics": _THESIS_STAGE, "dsp_stage": _THESIS_STAGE,
           "project_on_support": _SUPPORT, "advance_on_support": _SUPPORT}
"""The module whose Python code calls each thesis-part function (where :func:`_compile_part` stands in for it)."""


def _dispatchers(parts: tuple[str, ...] = PARTS) -> dict[str, object]:
    import importlib

    return {name: getattr(importlib.import_module(HOME[name]), name) for part in parts for name in PLAN[part]
            if name in ENTRY_POINTS}


def cache_ready(parts: tuple[str, ...] = PARTS) -> bool:
    """Whether numba's disk cache (``humanoid_sim.jit.CACHE_DIR``, keyed on the compiled sources) holds a current
    compilation of every entry point of ``parts``; False when unsure."""
    try:
        for disp in _dispatchers(parts).values():
            cache = getattr(disp, "_cache", None)
            index = cache._cache_file._load_index()  # {} when missing or stale (source stamp differs)
            if not index:
                return False
        return True
    except Exception:  # pragma: no cover - numba internals changed: fall back to the file heuristic
        from humanoid_sim.kernel import cache_present

        return cache_present()


class KernelBuild:
    """A running build: one child process per part (``python -m humanoid_sim.sim.builds PART SCENARIO``).

    ``start()`` launches them, ``wait()`` waits (raising :class:`KernelBuildError` when one fails), ``stop()`` kills
    any still running (idempotent; use it in a ``finally``).  ``scenario``: a scenario YAML whose objects give the
    argument types."""

    def __init__(self, scenario: str | Path, parts: tuple[str, ...] = PARTS, timeout: float = 600.0) -> None:
        self.scenario = Path(scenario).resolve()
        self.parts = tuple(parts)
        self.timeout = timeout
        self.procs: dict[str, subprocess.Popen] = {}
        self._err: dict[str, Any] = {}
        self._locks: str | None = None
        self.started = 0.0

    def start(self) -> KernelBuild:
        env = dict(os.environ)
        root = str(Path(__file__).resolve().parents[2])
        env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        env.setdefault("NUMBA_OPT", NUMBA_OPT)
        self._locks = tempfile.mkdtemp(prefix="humanoid_sim_kernel_locks_")
        env[LOCKS_ENV] = self._locks
        self.started = time.monotonic()
        for part in self.parts:
            # stderr to a file, not a pipe: a child writing more than a pipe holds would block
            self._err[part] = tempfile.TemporaryFile()
            self.procs[part] = subprocess.Popen(
                [sys.executable, "-m", "humanoid_sim.sim.builds", part, str(self.scenario)],
                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=self._err[part], env=env,
                # run from the package's own root: ``python -m`` puts the working directory first on sys.path, and
                # another checkout there would compile a different compiled.py than the one this process loads
                cwd=root)
        return self

    def wait(self, progress: Callable[[str, float], None] | None = None,
             tick: Callable[[], None] | None = None) -> float:
        """Wait for every part; ``progress(part, elapsed_s)`` when one finishes, ``tick()`` every ~0.25 s.  Returns
        the wall time since :meth:`start`, s."""
        failed: list[str] = []
        pending = dict(self.procs)
        last = 0.0
        while pending:
            for part, proc in list(pending.items()):
                if proc.poll() is None:
                    continue
                del pending[part]
                self._err[part].seek(0)
                err = self._err[part].read().decode("utf-8", "replace")
                if proc.returncode != 0:
                    failed.append(f"part {part} exited with status {proc.returncode}: {err.strip()[-1500:]}")
                elif progress is not None:
                    progress(part, time.monotonic() - self.started)
            if not pending:
                break
            now = time.monotonic()
            if now - self.started > self.timeout:
                self.stop()
                raise KernelBuildError(f"kernel build: parts {sorted(pending)} did not finish within {self.timeout} s")
            if tick is not None and now - last > 0.25:
                tick()
                last = now
            time.sleep(0.05)
        if failed:
            raise KernelBuildError("kernel build failed: " + "; ".join(failed))
        return time.monotonic() - self.started

    def stop(self) -> None:
        """Kill the parts still running and release their pipes (idempotent)."""
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        for fh in self._err.values():
            fh.close()
        if self._locks is not None:
            shutil.rmtree(self._locks, ignore_errors=True)
            self._locks = None


def build(scenario: str | Path, parts: tuple[str, ...] = PARTS, progress: Callable[[str, float], None] | None = None,
          timeout: float = 600.0) -> float:
    """Compile the kernel's entry points into numba's disk cache (one child process per part, in parallel) and
    wait for them; returns the wall time, s.  Raises :class:`KernelBuildError` when a child fails."""
    running = KernelBuild(scenario, parts, timeout).start()
    try:
        return running.wait(progress)
    finally:
        running.stop()


def _skip_callee_optimisation() -> bool:
    """In this (child) process, run numba's whole-module optimisation only for the libraries of the entry points.
    Returns whether the numba internals needed were found."""
    try:
        from numba.core import codegen
    except ImportError:  # pragma: no cover
        return False
    lib = getattr(codegen, "CPUCodeLibrary", None)
    original = getattr(lib, "_optimize_final_module", None)
    if original is None:  # pragma: no cover - numba internals changed
        return False

    def optimize_final_module(self) -> None:
        if self.name in ENTRY_POINTS:
            original(self)

    lib._optimize_final_module = optimize_final_module
    return True


def _skip_callee_machine_code() -> bool:
    """In this (child) process, generate machine code only for the libraries of :data:`KEEP_MACHINE_CODE`.

    numba compiles every ``@njit`` function (and every array expression and library overload it uses) to machine code
    as soon as it is typed, although a callee's code only ever runs linked into its callers' libraries; the children
    never call anything but entry points (:func:`_compile_part` does not even call those).  Here the other libraries
    keep their (function-optimised) LLVM IR for linking, are not handed to the JIT, and go to the disk cache as
    bitcode, which numba's cache reads back (compiling it to machine code then, in a process that calls one).
    Returns whether the numba internals needed were found."""
    try:
        from numba.core import codegen
    except ImportError:  # pragma: no cover
        return False
    lib = getattr(codegen, "CPUCodeLibrary", None)
    jit = getattr(codegen, "JITCPUCodegen", None)
    needed = ("_finalize_final_module", "serialize_using_object_code", "serialize_using_bitcode",
              "_finalize_dynamic_globals", "_verify_declare_only_symbols")
    if lib is None or jit is None or not all(hasattr(lib, n) for n in needed) or not hasattr(jit, "set_env"):
        return False  # pragma: no cover - numba internals changed
    finalize, serialize, set_env = lib._finalize_final_module, lib.serialize_using_object_code, jit.set_env

    def finalize_final_module(self) -> None:
        if self.name in KEEP_MACHINE_CODE:
            finalize(self)
            return
        self._finalize_dynamic_globals()  # what numba's version does, less handing the module to the JIT
        self._verify_declare_only_symbols()
        self._humanoid_sim_ir_only = True
        self._finalized = True

    def serialize_using_object_code(self):
        if getattr(self, "_humanoid_sim_ir_only", False):
            return self.serialize_using_bitcode()
        return serialize(self)

    def set_env_if_defined(self, env_name: str, env: object) -> None:
        # a library without machine code has no environment variable to point at its environment (never called)
        if self._engine.get_global_value_address(env_name):
            set_env(self, env_name, env)

    lib._finalize_final_module = finalize_final_module
    lib.serialize_using_object_code = serialize_using_object_code
    jit.set_env = set_env_if_defined
    return True


def _compile_once_across_children(folder: str) -> bool:
    """In this (child) process, compile each (function of :data:`COMPILED_MODULES`, signature) under an exclusive lock
    file in ``folder``, shared with the other children: a child that needs a callee the other one is compiling waits for
    it
    and then loads it from numba's disk cache instead of compiling it a second time.  The call graph has no cycles,
    so neither child can wait for a lock the waiting one holds.  Returns whether file locks are available."""
    try:
        import fcntl

        from numba.core import dispatcher, sigutils
    except ImportError:  # pragma: no cover - not POSIX: each child compiles what it needs
        return False
    original = dispatcher.Dispatcher.compile

    def compile(self, sig):
        py_func = getattr(self, "py_func", None)
        if getattr(py_func, "__module__", None) not in COMPILED_MODULES:
            return original(self, sig)
        args, _ = sigutils.normalize_signature(sig)
        if tuple(args) in self.overloads:
            return original(self, sig)
        key = hashlib.sha1(repr((py_func.__qualname__, tuple(str(a) for a in args))).encode()).hexdigest()
        with open(os.path.join(folder, key), "w") as fh:
            fcntl.flock(fh, fcntl.LOCK_EX)  # released when the file closes
            return original(self, sig)

    dispatcher.Dispatcher.compile = compile
    return True


class _CompileOnly:
    """Stands for a compiled function where its Python caller (:data:`CALLERS`) calls it: a call compiles it for the
    argument types (as numba's dispatcher types a call from Python) and runs nothing."""

    def __init__(self, dispatcher: Any) -> None:
        self.dispatcher = dispatcher

    def __call__(self, *args: Any) -> None:
        disp = self.dispatcher
        disp.compile(tuple(disp.typeof_pyval(a) for a in args))


def sample_stage(scenario: Path) -> tuple:
    """A :class:`StageKernel` of ``scenario`` and representative arguments of its calls, as a walk makes them:
    ``(kern, stage_args, q, v, data, n_rates)``, where ``stage_args(phase)`` gives the arguments of
    ``kern.stage(phase, ...)`` at the initial state (with its dynamics terms in ``data``) and ``n_rates`` is the
    integrator's stage count (``SupportKernel.warm_up``)."""
    import numpy as np
    import pinocchio as pin

    from humanoid_sim.controllers.thesis.command import CommandAccelerations
    from humanoid_sim.controllers.thesis.stage import StageKernel
    from humanoid_sim.dynamics.contact.constraints import record_anchors
    from humanoid_sim.dynamics.integrator import RungeKutta
    from humanoid_sim.references.chapter3 import ReferenceTrajectory
    from humanoid_sim.references.initial import initial_configuration
    from humanoid_sim.robot.actuators import Actuators
    from humanoid_sim.robot.model import load_model
    from humanoid_sim.scenario.schema import load_scenario

    hm = load_model()
    sc = load_scenario(scenario)
    q = initial_configuration(hm, sc.path)
    cmd = CommandAccelerations(hm, sc.controller, theta0=hm.theta_from_q(q))
    kern = StageKernel(hm, cmd, Actuators(hm))
    traj = ReferenceTrajectory(sc.path)
    v = np.zeros(hm.model.nv)
    data = hm.model.createData()
    pin.computeJointJacobiansTimeVariation(hm.model, data, q, v)
    pin.crba(hm.model, data, q)
    pin.nonLinearEffects(hm.model, data, q, v)
    n_rates = len(RungeKutta(hm.model, sc.simulation.method).tab.c)

    def stage_args(phase) -> tuple:
        k = next(i for i, ph in enumerate(traj.phases) if ph.name == phase.value)
        table = traj.dsp_table(k) if phase.is_double_support else traj.ssp_table(k)
        return record_anchors(hm.model, q, phase.contacts), q, v, data, table, traj.phases[k].t_start

    return kern, stage_args, q, v, data, n_rates


def _compile_part(part: str, scenario: Path) -> None:
    """Compile this part's functions (:data:`PLAN`) for the argument types a walk of ``scenario`` calls them with,
    in order, into numba's disk cache; no compiled code runs."""
    if part not in PLAN:
        raise SystemExit(f"kernel build: unknown part {part!r} (expected one of {PARTS})")
    import importlib

    import numpy as np

    from humanoid_sim.robot.phases import Phase

    if part == "balance":
        _compile_balance(scenario)
        return
    kern, stage_args, q, v, data, n_rates = sample_stage(scenario)
    ssp, dsp = Phase.LFFSSP, Phase.RFFDSP
    calls = {"ssp_stage": lambda: kern.stage(ssp, *stage_args(ssp)),
             "ssp_dynamics": lambda: kern.dynamics(ssp, stage_args(ssp)[0], q, v, data, np.empty(26)),
             "dsp_stage": lambda: kern.stage(dsp, *stage_args(dsp)),
             "project_on_support": lambda: kern.support.warm_up(q, n_rates),
             "advance_on_support": lambda: kern.support.warm_up(q, n_rates)}
    for name in PLAN[part]:
        for other in calls:  # the calls warm_up makes that are not this one's do nothing
            fn = getattr(importlib.import_module(HOME[other]), other)
            setattr(importlib.import_module(CALLERS[other]), other,
                    _CompileOnly(fn) if other == name else (lambda *a: None))
        calls[name]()


def _compile_balance(scenario: Path) -> None:
    """Compile ``balance_stage`` and ``balance_finish`` by one call of the balance controller at the scenario's
    initial state on chapter 3's trajectory of its path (no gait planning: the argument types are those of any
    walk).  Unlike the thesis parts this runs the compiled code once (~0.2 ms)."""
    import numpy as np

    from humanoid_sim.controllers.balance.controller import BalanceController
    from humanoid_sim.dynamics.contact import ContactDynamics
    from humanoid_sim.dynamics.contact.constraints import record_anchors
    from humanoid_sim.dynamics.welds import WeldModel
    from humanoid_sim.interfaces.controller import ControlContext, Observation
    from humanoid_sim.references.chapter3 import ReferenceTrajectory
    from humanoid_sim.references.initial import initial_configuration
    from humanoid_sim.robot.model import load_model
    from humanoid_sim.robot.phases import Phase
    from humanoid_sim.scenario.schema import load_scenario

    hm = load_model()
    sc = load_scenario(scenario)
    q = initial_configuration(hm, sc.path)
    traj = ReferenceTrajectory(sc.path)
    ctl = BalanceController()
    ctl.setup(ControlContext(hm, sc, traj, q, "pinocchio", WeldModel(ContactDynamics(hm.model))))
    phase = Phase(traj.phases[0].name)
    ctl(Observation(t=0.0, k=0, phase=phase, q=q, v=np.zeros(hm.model.nv),
                    anchors=record_anchors(hm.model, q, phase.contacts)))


def build_mujoco_reads(hm: Any, scenario: Any) -> None:
    """Compile every entry point of :mod:`humanoid_sim.engines.mujoco.compiled` into numba's disk cache (once after
    an install or an edit of a compiled module: ``humanoid_sim.jit``) by
    0.03 s of a MuJoCo walk from ``scenario``'s initial state (a parsed Scenario; its chapter-3 reference, no gait
    planning) under zero torques: the engine's real argument types, so that the walks load exactly these
    compilations.  How the short walk ends does not matter; a walk compiles what it did not reach."""
    from dataclasses import replace

    import numpy as np

    from humanoid_sim.engines.mujoco import compiled
    from humanoid_sim.sim.simulate import Simulator

    class _ZeroTorques:
        name = "zero torques (compiling the MuJoCo engine)"

        def setup(self, ctx) -> None:
            pass

        def __call__(self, obs) -> np.ndarray:
            return np.zeros(26)

    sc = replace(scenario, gait=replace(scenario.gait, hip_reference="thesis"), controller_class=None)
    try:
        Simulator(hm, sc, engine="mujoco", controller=_ZeroTorques()).run(t_end=0.03)
    except Exception:  # noqa: BLE001 - the real walk reports its own errors
        pass
    from numba import types

    for name in compiled.CONTACT_ENTRY_POINTS:   # the feet stood on >= 2 contacts: add the C-contiguous layout of <= 1
        disp = getattr(compiled, name)
        for sig in list(disp.signatures):
            c_sig = tuple(a.copy(layout="C") if isinstance(a, types.Array) else a for a in sig)
            if c_sig not in disp.signatures:
                disp.compile(c_sig)


if __name__ == "__main__":  # pragma: no cover - the child process of build()
    if len(sys.argv) != 3:
        sys.exit("usage: python -m humanoid_sim.sim.builds PART SCENARIO  (PART: ssp, dsp, support or balance)")
    _skip_callee_optimisation()
    _skip_callee_machine_code()
    if os.environ.get(LOCKS_ENV):
        _compile_once_across_children(os.environ[LOCKS_ENV])
    _compile_part(sys.argv[1], Path(sys.argv[2]))
