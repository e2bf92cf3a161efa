"""Locomotion parameters of thesis section 3.1 (the input of the trajectory generator).

All quantities are SI (m, s, rad) and resolved in the world frame of design.md section 3
(thesis inertial frame 0: x lateral, y forward, z up).  Index conventions: waypoints
``Phip[i]`` (thesis P_{i+1}) and segments ``i`` = path P_{i+1} -> P_{i+2} are 0-based here; the thesis
counts from 1.

Decisions (thesis silent or damaged; see docs/thesis-notes.md, "Reference trajectories"):

* The hip CoM height is constant (thesis L1393: "taken to be constant and the same during all
  phases"), so every waypoint must share the same z; a path that does not is rejected rather than
  silently flattened.
* Arcs must be minor arcs (chord < 2R, errata T-9); a semicircle (chord = 2R) has no unique centre
  choice in the pseudo-code of 3.2.1 and is rejected.
* ``k_Adj >= 1`` (t_z = t_SSP/k_Adj must fall inside the SSP, else the swing toe would land short of
  the step width; errata T-6) and ``0 < k_SH < 1``; ``SH`` must exceed the flat-toe height 0.015 m.
* Speeds in ``Vhip`` are magnitudes (thesis 3.1.2), hence must be >= 0.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from humanoid_sim.errors import InputError

#: Height of the toe point above the ground when the toe body lies flat (thesis L1592, m).
TOE_FLAT_HEIGHT = 0.015

_SEGMENT_FIELDS = ("R", "T_dir", "t_SSP", "PTR", "SW", "SH", "k_SH", "k_Adj", "dtheta_PLN", "dtheta_ADJ")
_PHASE_NAMES = ("LFFSSP", "RFFSSP")


class PathParamError(InputError):
    """A locomotion parameter is malformed or describes an impossible path.

    The message names the parameter (with the scenario location prefix), the offending index when
    there is one, and the offending value.
    """


def _plain(value: Any) -> Any:
    """numpy scalars/arrays as plain Python numbers/lists, so messages read 0.93, not np.float64(0.93)."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value


def _fail(where: str, name: str, msg: str, index: int | None = None, value: Any = None) -> PathParamError:
    idx = "" if index is None else f"[{index}]"
    val = "" if value is None else f" (value: {_plain(value)!r})"
    return PathParamError(f"{where}.{name}{idx}: {msg}{val}")


def _as_float_array(where: str, name: str, value: Any, ndim: int) -> np.ndarray:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise _fail(where, name, f"cannot be read as a numeric array ({exc})", value=value) from exc
    if arr.ndim != ndim:
        raise _fail(where, name, f"expected a {ndim}-D array, got shape {arr.shape}")
    bad = np.argwhere(~np.isfinite(arr))
    if bad.size:
        i = tuple(int(j) for j in bad[0])
        raise _fail(where, name, "must be finite", index=i[0] if ndim == 1 else i, value=float(arr[i]))
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class PathParams:
    """Locomotion definition of thesis section 3.1, validated on construction.

    Attributes
    ----------
    Phip : (n, 3) hip (Body-17 CoM) waypoints P_1..P_n, world frame, m (3.1.1).
    Vhip : (2n-1,) speeds [V_1, V_12, V_2, ..., V_n-1,n, V_n] of the hip CoM, m/s (3.1.2).
        ``Vhip[2i]`` is the speed at waypoint i, ``Vhip[2i+1]`` at the SSP/DSP switch of segment i.
    R : (n-1,) arc radius of each segment, m (3.1.3).
    T_dir : (n-1,) +1 turn left (centre on the left of P_k -> P_k+1), -1 turn right (3.1.9).
    t_SSP : (n-1,) single-support duration, s (3.1.4).
    PTR : (n-1,) t_SSP / t_DSP ratio (3.1.4).
    SW : (n-1,) step width, m: the swing toe lands at radius R -+ SW/2 (3.1.5, eqs. 3.32/3.33).
    SH : (n-1,) swing-toe height reached at k_SH * t_SSP, m, absolute z (3.1.6, errata T-7).
    k_SH : (n-1,) fraction of t_SSP at which the toe is at SH (3.1.6).
    k_Adj : (n-1,) t_z = t_SSP / k_Adj, time when the swing radius reaches R_f (3.1.7).
    dtheta_PLN, dtheta_ADJ : (n-1,) angular leads of 3.1.8, rad.
    toe_R0, toe_L0 : (3,) initial toe points P_tpR,i / P_tpL,i (thesis PRi/PLi), world, m.
    foot_R0, foot_L0 : (3, 3) initial orientations C^(0,1) / C^(0,2) of Bodies 1 / 2 (FRO_i/FLO_i).
    first_phase : "LFFSSP" (default, errata 6.1) or "RFFSSP": the SSP of segment 0.
    """

    Phip: np.ndarray
    Vhip: np.ndarray
    R: np.ndarray
    T_dir: np.ndarray
    t_SSP: np.ndarray
    PTR: np.ndarray
    SW: np.ndarray
    SH: np.ndarray
    k_SH: np.ndarray
    k_Adj: np.ndarray
    dtheta_PLN: np.ndarray
    dtheta_ADJ: np.ndarray
    toe_R0: np.ndarray
    toe_L0: np.ndarray
    foot_R0: np.ndarray
    foot_L0: np.ndarray
    first_phase: str = "LFFSSP"

    # ------------------------------------------------------------------ construction
    def __post_init__(self) -> None:
        self._validate("path")

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], where: str = "path") -> PathParams:
        """Build from a mapping with exactly the field names (the ``path:`` block of a scenario YAML).

        Raises :class:`PathParamError` for a missing or unknown key or any invalid value; messages are
        prefixed with ``where``.
        """
        if not isinstance(d, Mapping):
            raise PathParamError(f"{where}: expected a mapping, got {type(d).__name__}")
        names = [f.name for f in fields(cls)]
        unknown = sorted(set(d) - set(names))
        if unknown:
            raise PathParamError(f"{where}: unknown key(s) {unknown}; allowed: {names}")
        required = [n for n in names if n != "first_phase"]
        missing = [n for n in required if n not in d]
        if missing:
            raise PathParamError(f"{where}: missing key(s) {missing}")
        obj = object.__new__(cls)
        for n in names:
            object.__setattr__(obj, n, d.get(n, "LFFSSP") if n == "first_phase" else d[n])
        obj._validate(where)
        return obj

    # ------------------------------------------------------------------ validation
    def _validate(self, where: str) -> None:
        set_ = lambda n, v: object.__setattr__(self, n, v)  # noqa: E731 (frozen dataclass)
        P = _as_float_array(where, "Phip", self.Phip, 2)
        if P.shape[1] != 3 or P.shape[0] < 2:
            raise _fail(where, "Phip", f"expected shape (n, 3) with n >= 2, got {P.shape}")
        n = P.shape[0]
        set_("Phip", P)
        # thesis L1393: the hip CoM height is constant over the whole path.
        for i in range(1, n):
            if abs(P[i, 2] - P[0, 2]) > 1e-9:
                raise _fail(where, "Phip", f"z must equal Phip[0][2] = {float(P[0, 2])!r} (constant hip height, "
                            "thesis L1393)", index=i, value=P[i].tolist())
        V = _as_float_array(where, "Vhip", self.Vhip, 1)
        if V.shape[0] != 2 * n - 1:
            raise _fail(where, "Vhip", f"expected 2n-1 = {2 * n - 1} entries for n = {n} waypoints, "
                        f"got {V.shape[0]}")
        for i, v in enumerate(V):
            if v < 0:
                raise _fail(where, "Vhip", "speeds are magnitudes and must be >= 0", index=i, value=float(v))
        set_("Vhip", V)
        for name in _SEGMENT_FIELDS:
            a = _as_float_array(where, name, getattr(self, name), 1)
            if a.shape[0] != n - 1:
                raise _fail(where, name, f"expected n-1 = {n - 1} entries (one per segment), got {a.shape[0]}")
            set_(name, a)
        for i in range(n - 1):
            self._check_segment(where, i)
        for name in ("toe_R0", "toe_L0"):
            a = _as_float_array(where, name, getattr(self, name), 1)
            if a.shape != (3,):
                raise _fail(where, name, f"expected 3 entries, got shape {a.shape}")
            set_(name, a)
        for name in ("foot_R0", "foot_L0"):
            a = _as_float_array(where, name, getattr(self, name), 2)
            if a.shape != (3, 3):
                raise _fail(where, name, f"expected a 3x3 matrix, got shape {a.shape}")
            # 1e-6: orientations typed into YAML with ~7 significant digits must still pass.
            if not np.allclose(a @ a.T, np.eye(3), atol=1e-6) or np.linalg.det(a) < 0:
                raise _fail(where, name, "is not a rotation matrix (orthonormal, det +1)", value=a.tolist())
            set_(name, a)
        if self.first_phase not in _PHASE_NAMES:
            raise _fail(where, "first_phase", f"must be one of {_PHASE_NAMES}", value=self.first_phase)

    def _check_segment(self, where: str, i: int) -> None:
        def positive(name: str) -> None:
            v = float(getattr(self, name)[i])
            if not v > 0:
                raise _fail(where, name, "must be > 0", index=i, value=v)

        for name in ("R", "t_SSP", "PTR", "SW"):
            positive(name)
        r = float(self.R[i])
        d = self.Phip[i + 1, :2] - self.Phip[i, :2]
        chord = float(np.hypot(d[0], d[1]))
        if chord <= 0.0:
            raise _fail(where, "Phip", f"waypoints {i} and {i + 1} coincide in the ground plane", index=i + 1,
                        value=self.Phip[i + 1].tolist())
        if not chord < 2.0 * r:
            raise _fail(where, "R", f"arc cannot exist: radius is not above half the chord "
                        f"|P[{i + 1}]-P[{i}]|/2 = {chord / 2:.6g} m", index=i, value=r)
        td = float(self.T_dir[i])
        if td not in (1.0, -1.0):
            raise _fail(where, "T_dir", "must be +1 (left) or -1 (right)", index=i, value=td)
        kadj = float(self.k_Adj[i])
        if not kadj >= 1.0:
            raise _fail(where, "k_Adj", "must be >= 1 so that t_z = t_SSP/k_Adj lies within the SSP",
                        index=i, value=kadj)
        ksh = float(self.k_SH[i])
        if not 0.0 < ksh < 1.0:
            raise _fail(where, "k_SH", "must lie in (0, 1)", index=i, value=ksh)
        sh = float(self.SH[i])
        if not sh > TOE_FLAT_HEIGHT:
            raise _fail(where, "SH", f"must exceed the flat-toe height {TOE_FLAT_HEIGHT} m", index=i, value=sh)
        if not self.SW[i] / 2.0 < r:
            raise _fail(where, "SW", f"half the step width must be below the radius R[{i}] = {r}",
                        index=i, value=float(self.SW[i]))

    # ------------------------------------------------------------------ convenience
    @property
    def n_waypoints(self) -> int:
        return int(self.Phip.shape[0])

    @property
    def n_segments(self) -> int:
        return int(self.Phip.shape[0]) - 1

    @property
    def t_DSP(self) -> np.ndarray:
        """DSP durations t_DSP,k = t_SSP,k / PTR_k, s (thesis L1330)."""
        return self.t_SSP / self.PTR
