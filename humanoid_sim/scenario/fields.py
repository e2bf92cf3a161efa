"""The building blocks of scenario validation: value ranges and the checks of keys, numbers and vectors.

Every check raises :class:`ScenarioError` with a message that names the file, the field path with its index
(``path.R[3]``), the value and what was expected.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from humanoid_sim.errors import InputError


class ScenarioError(InputError):
    """Invalid scenario file: the message names the file, the field, the value and the expectation."""


@dataclass(frozen=True)
class Num:
    """Expected number: ``what`` (with unit) in the interval from ``lo`` to ``hi`` (open ends where asked);
    ``choices`` restricts it to a finite set."""

    what: str
    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple[float, ...] | None = None

    def describe(self) -> str:
        if self.choices is not None:
            return f"{self.what}, one of {', '.join(f'{c:g}' for c in self.choices)}"
        if self.lo == -math.inf and self.hi == math.inf:
            return f"{self.what} (finite)"
        if self.hi == math.inf:
            return f"{self.what} {'>' if self.lo_open else '>='} {self.lo:g}"
        if self.lo == -math.inf:
            return f"{self.what} {'<' if self.hi_open else '<='} {self.hi:g}"
        return (f"{self.what} in {'(' if self.lo_open else '['}{self.lo:g}, {self.hi:g}"
                f"{')' if self.hi_open else ']'}")

    def accepts(self, v: float) -> bool:
        if self.choices is not None:
            return v in self.choices
        lo_ok = v > self.lo if self.lo_open else v >= self.lo
        hi_ok = v < self.hi if self.hi_open else v <= self.hi
        return lo_ok and hi_ok


def suggest_key(key: str, allowed: Sequence[str]) -> str:
    """'; did you mean ...?' for a misspelt key, else the allowed keys (message tail)."""
    close = difflib.get_close_matches(key, list(allowed), n=1, cutoff=0.5)
    if close:
        return f"; did you mean {close[0]!r}?"
    listed = ", ".join(list(allowed)[:12]) + (", ..." if len(allowed) > 12 else "")
    return f"; allowed: {listed}"


def mapping_of(src: str, where: str, value: Any) -> dict:
    if not isinstance(value, dict):
        raise ScenarioError(f"{src}: {where}: expected a mapping of keys to values, got {type(value).__name__} "
                            f"({show(value)})")
    return value


def check_keys(src: str, where: str, d: dict, allowed: Sequence[str]) -> None:
    for k in d:
        if not isinstance(k, str) or k not in allowed:
            raise ScenarioError(f"{src}: {where + '.' if where else ''}{k}: unknown key{suggest_key(str(k), allowed)}")


def show(value: Any, limit: int = 80) -> str:
    """repr of a value, shortened for messages."""
    r = repr(value)
    return r if len(r) <= limit else r[:limit - 3] + "..."


def type_hint(value: Any) -> str:
    if isinstance(value, bool):
        return " (a boolean)"
    if isinstance(value, str):
        try:
            float(value)
        except ValueError:
            return " (a string)"
        if "e" in value.lower():
            return " (a string: YAML 1.1 reads an exponent without a dot and a sign as text; write e.g. 1.0e+3)"
        return " (a string: write the number without quotes)"
    if value is None:
        return " (empty)"
    name = type(value).__name__
    return f" ({'an' if name[0] in 'aeiou' else 'a'} {name})"


def number(src: str, where: str, value: Any, rng: Num) -> float:
    """A finite real number in ``rng``; booleans and numeric strings are rejected."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ScenarioError(f"{src}: {where}: expected {rng.describe()}, got {show(value)}{type_hint(value)}")
    v = float(value)
    if not math.isfinite(v) or not rng.accepts(v):
        raise ScenarioError(f"{src}: {where}: expected {rng.describe()}, got {show(value)}")
    return v


def vector(src: str, where: str, value: Any, n: int, rng: Num, what: str) -> list[float]:
    """A YAML list of exactly ``n`` numbers in ``rng``."""
    if not isinstance(value, list):
        raise ScenarioError(f"{src}: {where}: expected a list of {n} {what}, got {show(value)}{type_hint(value)}")
    if len(value) != n:
        raise ScenarioError(f"{src}: {where}: expected {n} entries ({what}), got {len(value)}: {show(value)}")
    return [number(src, f"{where}[{i}]", x, rng) for i, x in enumerate(value)]


def flat_section(src: str, name: str, raw: Any, cls, checks: dict[str, Any]) -> Any:
    """A flat section of scalars: each key is a :class:`Num`, a tuple of string choices, or
    ``("optional", Num)`` (``null`` allowed)."""
    if raw is None:
        return cls()
    d = mapping_of(src, name, raw)
    check_keys(src, name, d, tuple(checks))
    kwargs: dict[str, Any] = {}
    for k, v in d.items():
        spec = checks[k]
        if isinstance(spec, tuple) and spec and spec[0] == "optional":
            kwargs[k] = None if v is None else number(src, f"{name}.{k}", v, spec[1])
        elif isinstance(spec, tuple):
            if not isinstance(v, str) or v not in spec:
                raise ScenarioError(f"{src}: {name}.{k}: expected one of {', '.join(spec)}, got {show(v)}")
            kwargs[k] = v
        else:
            kwargs[k] = number(src, f"{name}.{k}", v, spec)
    return cls(**kwargs)
