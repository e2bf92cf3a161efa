"""humanoid_sim: a Pinocchio re-implementation of Akalin's (METU 2010) 3-D biped walking simulator."""

from pathlib import Path

__version__ = "0.1.0"

PACKAGE_DIR = Path(__file__).resolve().parent
MODELS_DIR = PACKAGE_DIR.parent / "models"
"""Where the robot YAML and generated URDF live (repository layout, editable install)."""
