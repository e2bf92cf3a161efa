"""Where the package's data lies: the robot description, the shipped scenarios and sweeps.

The files are package data (``humanoid_sim/data/``), so a built wheel carries them. In the repository,
``humanoid_sim/data/models``, ``params``, ``sweeps`` and ``designs`` point at the top-level ``models/``,
``scripts/params/``, ``scripts/sweeps/`` and ``scripts/designs/``, where a developer edits them.
"""

from __future__ import annotations

import os
from pathlib import Path

from humanoid_sim.errors import InputError

PACKAGE_DIR = Path(__file__).resolve().parent
DATA_DIR = PACKAGE_DIR / "data"
MODELS_DIR = DATA_DIR / "models"
"""The robot's body table (``thesis_humanoid.yaml``) and its generated URDF."""
SCENARIOS_DIR = DATA_DIR / "params"
"""The shipped scenarios: the thesis's ``sim1``-``sim3`` and the feasible ``*_zmp`` walks."""
SWEEPS_DIR = DATA_DIR / "sweeps"
"""The shipped sweep files."""
DESIGNS_DIR = DATA_DIR / "designs"
"""The shipped design files of ``humanoid-optimize``."""


def cache_dir() -> Path:
    """Where generated files are kept between runs (robot variants' URDFs): ``$HUMANOID_SIM_CACHE``, else
    ``$XDG_CACHE_HOME/humanoid_sim``, else ``~/.cache/humanoid_sim``."""
    if os.environ.get("HUMANOID_SIM_CACHE"):
        return Path(os.environ["HUMANOID_SIM_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "humanoid_sim"


def scenario_names() -> list[str]:
    """The names of the shipped scenarios (``sim1``, ``sim1_zmp``, ...), sorted."""
    return sorted(p.stem for p in SCENARIOS_DIR.glob("*.yaml"))


def scenario_path(scenario: str | Path) -> Path:
    """The YAML file of ``scenario``: a path to a file, or the name of a shipped scenario (``"sim1_zmp"``).

    Raises:
        InputError: neither an existing file nor a shipped scenario's name.
    """
    path = Path(scenario)
    if path.suffix in (".yaml", ".yml") or path.exists():
        return path
    shipped = SCENARIOS_DIR / f"{scenario}.yaml"
    if shipped.is_file():
        return shipped
    raise InputError(f"scenario: {str(scenario)!r} is neither a YAML file nor a shipped scenario; expected a path or "
                     f"one of {', '.join(scenario_names())}")


__all__ = ["DATA_DIR", "DESIGNS_DIR", "MODELS_DIR", "PACKAGE_DIR", "SCENARIOS_DIR", "SWEEPS_DIR", "cache_dir",
           "scenario_names", "scenario_path"]
