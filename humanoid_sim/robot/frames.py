"""The task frames of the humanoid: the frames the controllers' tasks and the compiled kernel evaluate."""

from __future__ import annotations

TASK_FRAMES = ["Pc_17", "O_17", "P_tpR", "P_tpL", "O_1", "O_2", "O_3", "O_4"]
"""Body 17's CoM (Pc_17) and orientation (O_17), the right and left toe points (P_tpR, P_tpL), the toe bodies
(O_1 right, O_2 left) and the feet's main bodies (O_3 right, O_4 left); the compiled kernel's frame rows follow
this order."""
