"""The simulation log: named signals with units, saved as ``results.npz`` and ``summary.json``.

Every logged signal is an array whose first axis is the step index (one row per integration step, the state
at the start of the step and the controller outputs of its first stage).  ``results.npz`` also holds
``signal_units`` (a JSON string: signal -> unit and meaning) and ``phase_names``.  Files are written atomically
(temporary file in the same folder, then rename), so an interrupted run never leaves a half-written file.
"""

from __future__ import annotations

import json
import os
import tempfile
import threading
from pathlib import Path
from typing import Any

import numpy as np

SIGNALS: dict[str, tuple[str, str]] = {
    # name: (unit, meaning)
    "t": ("s", "simulation time"),
    "phase": ("-", "index of the current phase (thesis PHASE_N - 1)"),
    "basic_phase": ("-", "0 LFFSSP, 1 RFFDSP, 2 RFFSSP, 3 LFFDSP"),
    "q": ("m, -, rad", "pinocchio configuration: O_17 position, quaternion (x y z w), joint angles"),
    "v": ("m/s, rad/s", "pinocchio velocity: O_17 twist in its frame, joint rates"),
    "a": ("m/s^2, rad/s^2", "pinocchio acceleration: O_17 spatial acceleration in its frame, joint accelerations"),
    "theta": ("rad", "thesis joint angles, eq. 4.1 order"),
    "theta_dot": ("rad/s", "thesis joint rates"),
    "theta_ddot": ("rad/s^2", "thesis joint accelerations from the contact dynamics"),
    "theta_ddot_cmd": ("rad/s^2", "optimum command accelerations (thesis 5.1)"),
    "T_cmd": ("N m", "computed-torque actuator torques before saturation, eq. 4.69 T-bar order"),
    "T": ("N m", "applied actuator torques after saturation, eq. 4.69 T-bar order"),
    "saturated": ("-", "true where the actuator torque hit its limit"),
    "tau": ("N m", "applied generalized torques (pinocchio v order)"),
    "hip_p": ("m", "Body-17 CoM position, world"),
    "hip_p_ref": ("m", "Body-17 CoM reference position at time t on the nominal schedule (the planned motion)"),
    "hip_p_ctrl_ref": ("m", "Body-17 CoM reference the controller used at time t: the current phase's reference, "
                       "clamped to its nominal window (thesis 6.1.1, errata T-3)"),
    "hip_v": ("m/s", "Body-17 CoM velocity, world"),
    "hip_v_ref": ("m/s", "Body-17 CoM reference velocity (planned motion at time t), world"),
    "hip_R": ("-", "Body-17 orientation C^(0,17)"),
    "hip_R_ref": ("-", "Body-17 reference orientation"),
    "hip_yaw": ("rad", "Body-17 yaw (x-axis heading from world x), unwrapped"),
    "hip_yaw_ref": ("rad", "Body-17 reference yaw, unwrapped"),
    "toe_R_p": ("m", "right toe point P_tpR, world"),
    "toe_R_p_ref": ("m", "right toe point reference"),
    "toe_L_p": ("m", "left toe point P_tpL, world"),
    "toe_L_p_ref": ("m", "left toe point reference"),
    "foot_R_R": ("-", "Body-1 orientation C^(0,1)"),
    "foot_L_R": ("-", "Body-2 orientation C^(0,2)"),
    "body_force": ("N", "ground force F_0,k on bodies 1, 2, 3, 4 in body frame k (thesis convention, K-7)"),
    "body_moment": ("N m", "ground moment M_0,k about the CoM of bodies 1, 2, 3, 4 in body frame k"),
    "foot_wrench": ("N, N m", "total ground wrench on the right [0] and left [1] foot, world frame, "
                    "force and moment about the world origin"),
    "cop": ("m", "centre of pressure of the right [0] and left [1] foot on z = 0 (nan off the ground)"),
    "in_contact": ("-", "right [0] / left [1] foot carries a constraint"),
    "zmp": ("m", "whole-body zero-moment point on z = 0 (nan if the normal force is not positive)"),
    "drift_position": ("m", "largest weld position drift of the step"),
    "drift_orientation": ("rad", "largest weld orientation drift of the step"),
    "dynamics_residual": ("N m", "||M a + h - tau - J^T lambda||_inf"),
}


_UMASK_LOCK = threading.Lock()


def _umask() -> int:
    """The process's file-creation mask (read by setting and restoring it; under a lock, since it is global)."""
    with _UMASK_LOCK:
        mask = os.umask(0o022)
        os.umask(mask)
    return mask


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder and a rename.

    The file gets the mode a plain ``open(path, "wb")`` would give it (0666 less the umask, usually 0644), not the
    0600 of the temporary file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        if hasattr(os, "fchmod"):  # POSIX (mkstemp's 0600 is what other systems' permissions ignore anyway)
            os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_text(path: Path, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


class SimLog:
    """The signals of :data:`SIGNALS`, accumulated row by row (:meth:`append`) or given as whole columns
    (:meth:`from_columns`, what the simulator does after its loop)."""

    def __init__(self) -> None:
        self.rows: dict[str, list[Any]] = {k: [] for k in SIGNALS}
        self._columns: dict[str, np.ndarray] | None = None

    @classmethod
    def from_columns(cls, columns: dict[str, np.ndarray]) -> SimLog:
        """A log holding whole columns (first axis = step index; every signal of :data:`SIGNALS`, same length)."""
        missing = set(SIGNALS) - set(columns)
        extra = set(columns) - set(SIGNALS)
        if missing or extra:
            raise KeyError(f"log columns: missing {sorted(missing)}, unknown {sorted(extra)}")
        lengths = {k: len(v) for k, v in columns.items()}
        if len(set(lengths.values())) > 1:
            raise ValueError(f"log columns: different lengths {lengths}")
        log = cls()
        log._columns = {k: np.asarray(columns[k]) for k in SIGNALS}
        return log

    def _to_rows(self) -> None:
        if self._columns is not None:
            self.rows = {k: list(np.array(c, copy=True)) for k, c in self._columns.items()}
            self._columns = None

    def append(self, **values: Any) -> None:
        missing = set(SIGNALS) - set(values)
        extra = set(values) - set(SIGNALS)
        if missing or extra:
            raise KeyError(f"log row: missing {sorted(missing)}, unknown {sorted(extra)}")
        self._to_rows()
        for k, v in values.items():
            self.rows[k].append(np.array(v, copy=True))

    def __len__(self) -> int:
        if self._columns is not None:
            return len(self._columns["t"])
        return len(self.rows["t"])

    def arrays(self) -> dict[str, np.ndarray]:
        if self._columns is not None:
            return {k: c.copy() for k, c in self._columns.items()}
        out = {}
        for k, rows in self.rows.items():
            out[k] = np.array(rows) if rows else np.zeros((0,))
        return out

    def save(self, path: Path, phase_names: list[str], extra: dict[str, np.ndarray] | None = None) -> None:
        """Save ``results.npz`` atomically: the signals, ``phase_names``, ``signal_units`` and the arrays of
        ``extra`` (``Run.write`` adds the column names ``theta_names``, ``T_names``, ``q_names``, ``v_names`` and the
        ``engine``)."""
        import io

        arrays: dict[str, Any] = self.arrays()
        if extra:
            arrays.update(extra)
        buf = io.BytesIO()
        np.savez_compressed(buf, **arrays, phase_names=np.array(phase_names),
                            signal_units=np.array(json.dumps({k: {"unit": u, "meaning": m}
                                                              for k, (u, m) in SIGNALS.items()})))
        atomic_write_bytes(path, buf.getvalue())


def load_results(path: str | Path) -> dict[str, np.ndarray]:
    """Load a ``results.npz`` into a plain dict of arrays."""
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}
