"""Compiled per-stage kernel of the simulator (numba), mirroring the NumPy reference path.

The reference implementation of every formula is the readable NumPy/Pinocchio code in
:mod:`humanoid_sim.command`, :mod:`humanoid_sim.contact` and :mod:`humanoid_sim.actuators`; it is what the
thesis oracle and the independent checks (scipy minimisation, finite differences, MuJoCo) test.  Measured
(``scripts/bench.py``), a single-support stage of that path costs ~300 us, of which Pinocchio's algorithms take
~15 us: the rest is the overhead of ~150 small NumPy and binding calls.  This package computes the same stage in
one compiled call (:mod:`.compiled`, driven by :class:`.stage.StageKernel`), in all four phases:

- Pinocchio still does the dynamics passes (``computeJointJacobiansTimeVariation``, ``crba``,
  ``nonLinearEffects``) and the rare stages the kernel leaves to the reference path (an actuator saturates: the
  forward dynamics of the clipped torques);
- the kernel does the glue: the phase's references (from ``ReferenceTrajectory.ssp_table``), placements by forward
  kinematics of the (fixed, revolute + free-flyer) tree, frame Jacobians and bias accelerations from Pinocchio's
  joint Jacobians, the controller's cost rows and normal equations (thesis 5.1, with the closed chain in double
  support), the computed torque under the phase's constraints (5.2), the thesis actuator torques T and the saturation check, the quantities the log records, and, per
  integrator stage, the Runge-Kutta combination, integration and projection onto the support foot.

``tests/test_kernel.py`` checks every kernel output against Pinocchio and the reference path at many states of
real walks, and a whole walk against the reference walk; ``Simulator`` repeats a short comparison at start-up
(``ThesisController.check_kernel``).  Without numba installed the simulator uses the reference path (:data:`AVAILABLE`
is then False).
"""

from __future__ import annotations

try:  # pragma: no cover - exercised by whichever environment runs the tests
    import numba  # noqa: F401

    AVAILABLE = True
except ImportError:  # pragma: no cover
    AVAILABLE = False


def cache_present() -> bool:
    """Whether numba's disk cache of the kernel seems to exist (its index files next to ``compiled.py`` or under
    NUMBA_CACHE_DIR): when not, the first use compiles it (up to a minute).  A heuristic for a progress message only."""
    import os
    from pathlib import Path

    here = Path(__file__).resolve().parent
    places = [here / "__pycache__"]
    if os.environ.get("NUMBA_CACHE_DIR"):
        places.append(Path(os.environ["NUMBA_CACHE_DIR"]))
    return any(any(place.rglob("compiled.ssp_stage-*.nbi")) for place in places if place.is_dir())
