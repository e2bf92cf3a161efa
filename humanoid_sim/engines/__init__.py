"""Engines: what advances the state under the phase's contacts (interface: :class:`.base.Engine`).

- ``pinocchio`` (:class:`.weld.WeldEngine`, the default): the thesis's welded feet on Pinocchio's KKT dynamics;
- ``thesis`` (:class:`.oracle.OracleEngine`): the NumPy transcription of the thesis's equations (slow; for
  comparison).
"""

from __future__ import annotations

from typing import Any

ENGINE_NAMES = ("pinocchio", "thesis")
"""Names ``walk.py --engine`` accepts, in the order the help lists them."""


def make_engine(name: str, hm: Any, scenario: Any, traj: Any, compiled: bool | None = None) -> Any:
    """The engine called ``name`` for one run (``compiled``: the weld engine's compiled integration, see
    :class:`.weld.WeldEngine`)."""
    if name == "pinocchio":
        from humanoid_sim.engines.weld import WeldEngine

        return WeldEngine(hm, scenario, traj, compiled=compiled)
    if name == "thesis":
        from humanoid_sim.engines.oracle import OracleEngine

        return OracleEngine(hm, scenario, traj)
    raise ValueError(f"engine: {name!r} is not one of {ENGINE_NAMES}")


__all__ = ["ENGINE_NAMES", "make_engine"]
