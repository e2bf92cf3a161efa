"""The ``controller:`` section of a scenario: the thesis controller's weights and prediction times (Appendix B).

Key names are the thesis's, verbatim (``Wp_fa_LFFSSP``, ``Delta_t1_RFFDSP``, ...). The section is required only when
the thesis controller runs: the thesis gait without a ``controller_class``, or the zmp gait with
``gait.controller: thesis``. Weights are dimensionless diagonal entries; prediction times are in s.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from humanoid_sim.errors import InputError
from humanoid_sim.scenario.fields import Num, ScenarioError, check_keys, mapping_of, number, vector

TIME = Num("a prediction time in s", 0.0, 5.0, lo_open=True)
WEIGHT = Num("a weight", 0.0)


class ControllerParamError(InputError):
    """A controller weight or prediction time is missing or malformed (message names the key and value)."""


@dataclass(frozen=True)
class StepWeights:
    """Weights of one cost (one step of an SSP, or one chain of a DSP), diagonal entries."""

    dt: float
    W_p: np.ndarray      # (3,) position
    W_v: np.ndarray      # (6,) [linear; angular] velocity
    W_or: np.ndarray     # (3,) C_diag orientation
    W_q: np.ndarray      # (n,) joint deviation
    W_qdd: np.ndarray    # (n,) joint acceleration
    dt3: float = 0.0     # toe-joint penalty horizon (SSP step 2 only)
    W_p_toe: float = 0.0
    W_v_toe: float = 0.0


@dataclass(frozen=True)
class ControllerParams:
    """All weights and prediction times of Appendix B for the four phases and the upper body."""

    steps: dict[str, tuple[StepWeights, StepWeights]]   # phase -> (a: hip/stance chain, b: swing/other chain)
    upper_Wp: np.ndarray
    upper_Wv: np.ndarray
    upper_dt: np.ndarray
    raw: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def from_dict(cls, c: dict[str, Any], where: str = "controller") -> ControllerParams:
        def vec(key: str, n: int) -> np.ndarray:
            if key not in c:
                raise ControllerParamError(f"{where}.{key}: missing (expected {n} non-negative weights)")
            v = np.atleast_1d(np.asarray(c[key], dtype=float))
            if v.shape != (n,):
                raise ControllerParamError(f"{where}.{key}: expected {n} entries, got {v.size}")
            bad = np.flatnonzero(~np.isfinite(v) | (v < 0))
            if bad.size:
                raise ControllerParamError(f"{where}.{key}[{bad[0]}]: expected a non-negative weight, got {v[bad[0]]}")
            return v

        def scal(key: str, positive: bool = False) -> float:
            v = vec(key, 1)[0]
            if positive and v <= 0:
                raise ControllerParamError(f"{where}.{key}: expected a positive time in s, got {v}")
            return float(v)

        steps = {}
        for ph, stance, other, toe in (("LFFSSP", "L", "R", "3"), ("RFFSSP", "R", "L", "4")):
            a = StepWeights(dt=scal(f"Delta_t1_{ph}", True), W_p=vec(f"Wp_fa_{ph}", 3), W_v=vec(f"Wv_fa_{ph}", 6),
                            W_or=vec(f"Wor_fa_{ph}", 3), W_q=vec(f"Wq{stance}_H_{ph}", 7),
                            W_qdd=vec(f"Wa_a_{ph}", 7))
            b = StepWeights(dt=scal(f"Delta_t2_{ph}", True), W_p=vec(f"Wp_fb_{ph}", 3), W_v=vec(f"Wv_fb_{ph}", 6),
                            W_or=vec(f"Wor_fb_{ph}", 3), W_q=vec(f"WqH_{other}_{ph}", 8),
                            W_qdd=vec(f"Wa_b_{ph}", 8), dt3=scal(f"Delta_t3_{ph}", True),
                            W_p_toe=scal(f"Wp_Tetha{toe}_{ph}"), W_v_toe=scal(f"Wv_Tetha{toe}_{ph}"))
            steps[ph] = (a, b)
        for ph, stance, other in (("LFFDSP", "L", "R"), ("RFFDSP", "R", "L")):
            # errata A-13: one prediction time per DSP (Delta_t1 = Delta_t2)
            dt = scal(f"Delta_t1_{ph}", True)
            a = StepWeights(dt=dt, W_p=vec(f"Wp_fa_{ph}", 3), W_v=vec(f"Wv_fa_{ph}", 6), W_or=vec(f"Wor_fa_{ph}", 3),
                            W_q=vec(f"Wq{stance}_H_{ph}", 7), W_qdd=vec(f"Wa_a_{ph}", 7))
            b = StepWeights(dt=dt, W_p=vec(f"Wp_fb_{ph}", 3), W_v=vec(f"Wv_fb_{ph}", 6), W_or=vec(f"Wor_fb_{ph}", 3),
                            W_q=vec(f"Wq{other}_H_{ph}", 8), W_qdd=vec(f"Wa_b_{ph}", 8))
            steps[ph] = (a, b)
        ks = range(18, 28)
        Wp = np.array([scal(f"WpTetha{k}") for k in ks])
        Wv = np.array([scal(f"WvTetha{k}") for k in ks])
        dts = np.array([scal(f"Delta_t{k}", True) for k in ks])
        return cls(steps=steps, upper_Wp=Wp, upper_Wv=Wv, upper_dt=dts, raw=dict(c))


def _controller_schema() -> dict[str, tuple[int, Num, bool]]:
    """Controller key -> (size, range, required).  Sizes of Appendix B / Table A.1; Wact has len(F) = 96
    entries (eq. 4.68).  Wact_* and Delta_t2_*DSP are accepted but optional: the fast path does not read them
    (errata A-3, A-13)."""
    s: dict[str, tuple[int, Num, bool]] = {}
    for p in ("LFFSSP", "RFFSSP"):
        for j in (1, 2, 3):
            s[f"Delta_t{j}_{p}"] = (1, TIME, True)
    for p in ("LFFDSP", "RFFDSP"):
        s[f"Delta_t1_{p}"] = (1, TIME, True)
        s[f"Delta_t2_{p}"] = (1, TIME, False)
    sizes = {"Wp_fa": 3, "Wv_fa": 6, "Wa_a": 7, "Wp_fb": 3, "Wv_fb": 6, "Wa_b": 8, "Wor_fa": 3, "Wor_fb": 3}
    for w, n in sizes.items():
        for p in ("LFFSSP", "RFFSSP", "LFFDSP", "RFFDSP"):
            s[f"{w}_{p}"] = (n, WEIGHT, True)
    for k in ("Wp_Tetha3_LFFSSP", "Wv_Tetha3_LFFSSP", "Wp_Tetha4_RFFSSP", "Wv_Tetha4_RFFSSP"):
        s[k] = (1, WEIGHT, True)
    for k in ("Wact_LFFDSP", "Wact_RFFDSP"):
        s[k] = (96, WEIGHT, False)
    for k, n in (("WqL_H_LFFSSP", 7), ("WqH_R_LFFSSP", 8), ("WqR_H_RFFSSP", 7), ("WqH_L_RFFSSP", 8),
                 ("WqL_H_LFFDSP", 7), ("WqR_H_LFFDSP", 8), ("WqR_H_RFFDSP", 7), ("WqL_H_RFFDSP", 8)):
        s[k] = (n, WEIGHT, True)
    for j in range(18, 28):
        s[f"WpTetha{j}"] = (1, WEIGHT, True)
        s[f"WvTetha{j}"] = (1, WEIGHT, True)
        s[f"Delta_t{j}"] = (1, TIME, True)
    return s


CONTROLLER_SCHEMA = _controller_schema()


def check_controller(src: str, raw: Any) -> dict[str, Any]:
    """Form of the ``controller`` block: keys, sizes, ranges.  Returns it unchanged."""
    d = mapping_of(src, "controller", raw)
    check_keys(src, "controller", d, tuple(CONTROLLER_SCHEMA))
    for k, (n, rng, required) in CONTROLLER_SCHEMA.items():
        if k not in d:
            if required:
                raise ScenarioError(f"{src}: controller.{k}: missing (expected "
                                    f"{'1 value' if n == 1 else f'{n} values'}, {rng.describe()})")
            continue
        if n == 1:
            number(src, f"controller.{k}", d[k], rng)
        else:
            vector(src, f"controller.{k}", d[k], n, rng, "weights")
    return d


def parse_controller(src: str, raw: Any) -> ControllerParams:
    """The ``controller`` section as :class:`ControllerParams` (its form checked by :func:`check_controller`).

    Raises:
        ScenarioError: a missing or unknown key, a wrong size, a value out of range.
    """
    d = check_controller(src, raw)
    try:
        return ControllerParams.from_dict(d, where="controller")
    except (ControllerParamError, TypeError, ValueError) as exc:
        raise ScenarioError(f"{src}: {exc}") from None


__all__ = ["CONTROLLER_SCHEMA", "ControllerParamError", "ControllerParams", "StepWeights", "check_controller",
           "parse_controller"]
