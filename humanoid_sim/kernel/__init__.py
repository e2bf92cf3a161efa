"""Shared compiled code (numba) of the simulator's fast paths, and the Python side of what several of them use.

The reference of every formula is the readable NumPy/Pinocchio code the thesis oracle and the independent checks
(scipy minimisation, finite differences, MuJoCo) test; each compiled module here is the twin of one reference
module, formula for formula:

- :mod:`.linalg`: small products and solves (LAPACK's algorithms, as the reference paths call them);
- :mod:`.kinematics`: Pinocchio's forward kinematics, frame placements and motions, SE(3) logarithms;
- :mod:`.contact`: :mod:`humanoid_sim.dynamics.contact` (weld and lock rows, computed torque);
- :mod:`.actuators`: ``Actuators.thesis_torques`` (:mod:`humanoid_sim.robot.actuators`);
- :mod:`.projection`: ``WeldEngine.project_on_support`` and the Runge-Kutta combination;
- :mod:`.log`: the per-stage log vector (the weld engine's stage record) and its named layout.

The twins of higher modules live beside their references: :mod:`humanoid_sim.references.chapter3.compiled`,
:mod:`humanoid_sim.controllers.thesis.compiled` (the thesis controller's whole stage),
:mod:`humanoid_sim.controllers.balance.compiled` (the balance controller's QP).  Arguments are grouped in the
NamedTuples of :mod:`.records`.  The Python side: :mod:`.tree` (the model's constant tables), :mod:`.support`
(projection, actuator tables, stage outputs).  Where numba caches the machine code: :mod:`humanoid_sim.jit`.

``tests/kernel/test_kernel.py`` checks every kernel output against Pinocchio and the reference path at many states
of real walks, and a whole walk against the reference walk.  Without numba installed the simulator uses the
reference paths (:data:`AVAILABLE` is then False).
"""

from __future__ import annotations

from humanoid_sim.jit import AVAILABLE, cache_present

__all__ = ["AVAILABLE", "cache_present"]
