"""Engines: what advances the state under the phase's contacts (interface:
:class:`humanoid_sim.interfaces.engine.Engine`).

- ``pinocchio`` (:class:`.weld.WeldEngine`, the default): the thesis's welded feet on Pinocchio's KKT dynamics;
- ``thesis`` (:class:`.oracle.OracleEngine`): the NumPy transcription of the thesis's equations (slow; for
  comparison);
- ``mujoco`` (:class:`.mujoco.MujocoEngine`): MuJoCo, with unilateral frictional contact instead of welds (would
  the walk stand on real ground?).
"""

from __future__ import annotations

from typing import Any

ENGINE_NAMES = ("pinocchio", "thesis", "mujoco")
"""Names ``walk.py --engine`` accepts, in the order the help lists them."""


def make_engine(name: str, hm: Any, scenario: Any, traj: Any, compiled: bool | None = None, **options: Any) -> Any:
    """The engine called ``name`` for one run (``compiled``: the weld engine's compiled integration, see
    :class:`.weld.WeldEngine`, and the MuJoCo engine's compiled ground reads, :class:`.mujoco.MujocoEngine`;
    ``options``: settings of the MuJoCo engine, :class:`.mujoco.MujocoEngineSettings` fields, e.g.
    ``control_period_s=0.001``; the weld engine takes ``control_period_s`` alone)."""
    allowed = {"pinocchio": {"control_period_s"}, "thesis": set()}.get(name)
    if allowed is not None and set(options) - allowed:
        raise ValueError(f"engine {name!r} takes no options {sorted(set(options) - allowed)}")
    if name == "pinocchio":
        from humanoid_sim.engines.weld import WeldEngine

        return WeldEngine(hm, scenario, traj, compiled=compiled, **options)
    if name == "thesis":
        from humanoid_sim.engines.oracle import OracleEngine

        return OracleEngine(hm, scenario, traj)
    if name == "mujoco":
        from humanoid_sim.engines.mujoco.engine import MujocoEngine

        return MujocoEngine(hm, scenario, traj, compiled=compiled, **options)
    raise ValueError(f"engine: {name!r} is not one of {', '.join(ENGINE_NAMES)}")


__all__ = ["ENGINE_NAMES", "make_engine"]
