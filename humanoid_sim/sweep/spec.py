"""Sweep files (YAML): schema, validation, and expansion into the walks of a sweep.

A sweep file names a base scenario and the parameters to vary, as dotted paths into the scenario document::

    base: ../params/sim3.yaml              # relative to this file's folder first, then to the working directory
    description: "speeds x step lengths"   # optional
    grid:                                  # every combination; the first key varies slowest
      path.Vhip: {scale: [0.8, 1.0, 1.2]}  # multiply every number at the path (a scalar or a nested list)
      path.SW: [0.28, 0.32]                # set the value; a scalar for a list (per segment) sets every element
      "path.Phip[*][1], path.dtheta_PLN": {scale: [0.9, 1.1]}   # several paths on one axis, same value
    random:                                # optional: n samples, uniform in [low, high), seeded
      n: 8
      seed: 1
      path.SH: {low: 0.05, high: 0.09}
      path.t_SSP: {scale: {low: 0.9, high: 1.1}}

Dotted paths: names separated by dots, each optionally followed by list indices ``[i]`` (0-based) or ``[*]``
(every element): ``simulation.t_end_s``, ``controller.Wp_fa_LFFSSP[2]``, ``path.Phip[*][1]`` (every waypoint's
y).  A missing mapping key is created (``simulation.t_end_s`` when the base scenario has no ``t_end_s``; a new
section such as ``gait.hip_reference``): whether the scenario accepts it is decided by the scenario schema
(:func:`humanoid_sim.scenario.schema.parse_scenario`), not here, so every key that schema accepts can be swept.

Walks: the grid's combinations (``itertools.product`` in file order) times the ``n`` random samples (the same
samples for every grid point, drawn sample by sample in file order from ``numpy.random.default_rng(seed)``);
without a grid, the samples; without ``random``, the grid.  Every generated scenario is validated with
:func:`~humanoid_sim.scenario.schema.parse_scenario` here, before any walk runs; the message names the walk and its
parameter values.  Each walk is identified by :func:`scenario_hash` of its generated document; two walks that
generate the same document are an error.

Every error is a :class:`SweepError` naming the file, the field (``grid.path.SW``), the value and what was
expected; the command prints it and exits with status 2 before anything runs or is written.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from humanoid_sim.errors import InputError

# The scenario module's YAML loader (safe, rejects duplicate keys): sweep files obey the same rules.
from humanoid_sim.scenario.fields import ScenarioError, suggest_key
from humanoid_sim.scenario.schema import parse_scenario, read_scenario_doc
from humanoid_sim.scenario.yamlio import read_yaml

TOP_KEYS = ("base", "description", "grid", "random")
RANDOM_KEYS = ("n", "seed")
MAX_WALKS = 100_000
"""Upper bound on the walks of one sweep file (each generated document is held in memory and validated)."""

_SEGMENT = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)((?:\[(?:\d+|\*)\])*)$")
_INDEX = re.compile(r"\[(\d+|\*)\]")
ALL = "*"
"""Path token meaning "every element of the list"."""


class SweepError(InputError):
    """Invalid sweep file: the message names the file, the field, the value and what was expected."""


# --------------------------------------------------------------------------------------------- dotted paths
@dataclass(frozen=True)
class DottedPath:
    """A parsed dotted path: ``text`` as written and ``tokens`` (str = mapping key, int = list index,
    :data:`ALL` = every list element)."""

    text: str
    tokens: tuple[str | int, ...]

    @classmethod
    def parse(cls, text: str, where: str) -> DottedPath:
        """Parse ``text``; ``where`` prefixes the error message."""
        tokens: list[str | int] = []
        for seg in text.strip().split("."):
            m = _SEGMENT.match(seg.strip())
            if m is None:
                raise SweepError(f"{where}: {text.strip()!r} is not a dotted path: expected names separated by "
                                 "dots, each optionally followed by [index] or [*] (e.g. path.SW, "
                                 "simulation.t_end_s, path.Phip[*][1])")
            tokens.append(m.group(1))
            for idx in _INDEX.findall(m.group(2)):
                tokens.append(ALL if idx == ALL else int(idx))
        return cls(text.strip(), tuple(tokens))

    def overlaps(self, other: DottedPath) -> bool:
        """Whether the two paths can address the same value (one is a prefix of the other; ``[*]`` matches
        any index)."""
        for a, b in zip(self.tokens, other.tokens):
            if a == b or (isinstance(a, int) and b == ALL) or (a == ALL and isinstance(b, int)):
                continue
            return False
        return True


_MISSING = object()


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _scaled(value: Any, factor: float, where: str) -> Any:
    """``value`` (a number or a nested list of numbers) times ``factor``."""
    if _is_number(value):
        return value * factor
    if isinstance(value, list):
        return [_scaled(v, factor, f"{where}[{i}]") for i, v in enumerate(value)]
    raise SweepError(f"{where}: scale needs a number or a list of numbers in the base scenario, found "
                     f"{_show(value)}")


def _leaf(current: Any, value: Any, mode: str, where: str) -> Any:
    if mode == "scale":
        if current is _MISSING:
            raise SweepError(f"{where}: scale needs a value to multiply, but the base scenario has none there")
        return _scaled(current, value, where)
    if isinstance(current, list) and not isinstance(value, (list, dict)):
        return [copy.deepcopy(value) for _ in current]  # a scalar for a list sets every element
    return copy.deepcopy(value)


def apply(doc: dict, path: DottedPath, value: Any, mode: str) -> None:
    """Set (``mode="set"``) or multiply (``mode="scale"``) the value at ``path`` in ``doc``, in place.
    Raises :class:`SweepError` when the path does not fit the document (an index into a mapping, a key into a
    list, an index out of range, a scale of a missing or non-numeric value)."""

    def walk(node: Any, i: int, done: str) -> None:
        tok = path.tokens[i]
        last = i == len(path.tokens) - 1
        if isinstance(tok, str) and tok != ALL:
            here = f"{done}.{tok}" if done else tok
            if not isinstance(node, dict):
                raise SweepError(f"{here}: {done} is {_kind(node)} in the base scenario, not a mapping")
            if last:
                node[tok] = _leaf(node.get(tok, _MISSING), value, mode, here)
                return
            if tok not in node:
                if mode == "scale" or not isinstance(path.tokens[i + 1], str) or path.tokens[i + 1] == ALL:
                    raise SweepError(f"{here}: missing in the base scenario (a new key can only be set, and only "
                                     "through mapping keys)")
                node[tok] = {}
            walk(node[tok], i + 1, here)
            return
        if not isinstance(node, list):
            raise SweepError(f"{done}[{tok}]: {done} is {_kind(node)} in the base scenario, not a list")
        indices = range(len(node)) if tok == ALL else [tok]
        for j in indices:
            here = f"{done}[{j}]"
            if j >= len(node):
                raise SweepError(f"{here}: index out of range, {done} has {len(node)} entries in the base scenario")
            if last:
                node[j] = _leaf(node[j], value, mode, here)
            else:
                walk(node[j], i + 1, here)

    walk(doc, 0, "")


def values_at(doc: Any, path: DottedPath) -> list[Any]:
    """Every value ``path`` addresses in ``doc``, flattened in document order ([] where the path does not fit:
    a missing key, an index out of range).  A list at the end of the path gives its numbers, nested lists
    flattened."""
    out: list[Any] = []

    def flat(node: Any) -> None:
        if isinstance(node, list):
            for v in node:
                flat(v)
        else:
            out.append(node)

    def walk(node: Any, i: int) -> None:
        if i == len(path.tokens):
            flat(node)
            return
        tok = path.tokens[i]
        if isinstance(tok, str) and tok != ALL:
            if isinstance(node, dict) and tok in node:
                walk(node[tok], i + 1)
            return
        if not isinstance(node, list):
            return
        for j in (range(len(node)) if tok == ALL else [tok]):
            if j < len(node):
                walk(node[j], i + 1)

    walk(doc, 0)
    return out


def _kind(x: Any) -> str:
    if isinstance(x, dict):
        return "a mapping"
    if isinstance(x, list):
        return "a list"
    return f"the value {_show(x)}"


def _show(value: Any, limit: int = 80) -> str:
    r = repr(value)
    return r if len(r) <= limit else r[:limit - 3] + "..."


# --------------------------------------------------------------------------------------------- hashing
def _canonical(x: Any) -> Any:
    """Document with every non-boolean number as a float (YAML's ``1`` and ``1.0`` are the same value to the
    scenario parser, so they hash alike)."""
    if isinstance(x, dict):
        return {str(k): _canonical(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_canonical(v) for v in x]
    if _is_number(x):
        return float(x)
    return x


def scenario_hash(doc: Any) -> str:
    """16 hex digits of the SHA-256 of the document's canonical JSON (sorted keys, numbers as floats in their
    shortest round-trip form): the key of a walk's row, stable across runs and machines."""
    text = json.dumps(_canonical(doc), sort_keys=True, separators=(",", ":"), ensure_ascii=False,
                      allow_nan=True, default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


# --------------------------------------------------------------------------------------------- axes, walks
@dataclass(frozen=True)
class Axis:
    """One swept dimension: the paths it writes, ``mode`` "set" or "scale", and either the grid ``values`` or
    the random interval [``low``, ``high``)."""

    field: str                       # "grid.<key>" or "random.<key>", for messages
    paths: tuple[DottedPath, ...]
    mode: str
    values: tuple[Any, ...] = ()
    low: float = math.nan
    high: float = math.nan

    @property
    def column(self) -> str:
        """Name of the table column: the paths as written, joined by commas, plus ``:scale`` for a factor."""
        return ",".join(p.text for p in self.paths) + (":scale" if self.mode == "scale" else "")

    def cell(self, value: Any) -> Any:
        """The table cell of ``value``: numbers, strings and booleans as they are (one type per column),
        anything else (lists, mixed kinds) as JSON text."""
        if self.mode == "scale" or self.values == ():
            return float(value)
        vals = self.values
        if all(_is_number(v) for v in vals):
            return float(value) if any(isinstance(v, float) for v in vals) else int(value)
        if all(isinstance(v, str) for v in vals) or all(isinstance(v, bool) for v in vals):
            return value
        return json.dumps(value, separators=(",", ":"))

    def set_in(self, doc: dict, value: Any) -> None:
        for p in self.paths:
            apply(doc, p, value, self.mode)


@dataclass(frozen=True)
class Walk:
    """One generated scenario: its index in the sweep, the swept values (column -> table cell), the document,
    its hash, and a label for messages."""

    index: int
    params: dict[str, Any]
    doc: dict
    scenario_hash: str
    label: str


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep file (not yet expanded)."""

    source: Path
    base_path: Path
    base_doc: dict
    description: str
    grid: tuple[Axis, ...]
    random: tuple[Axis, ...]
    n: int
    seed: int | None

    @property
    def axes(self) -> tuple[Axis, ...]:
        """Grid axes then random axes: the order of the parameter columns (the first two are mapped)."""
        return self.grid + self.random

    @property
    def n_walks(self) -> int:
        g = math.prod(len(a.values) for a in self.grid) if self.grid else 1
        return g * (self.n if self.random else 1)

    def samples(self) -> list[tuple[float, ...]]:
        """The random samples, one tuple per sample in the order of :attr:`random`."""
        if not self.random:
            return [()]
        rng = np.random.default_rng(self.seed)
        return [tuple(float(rng.uniform(a.low, a.high)) for a in self.random) for _ in range(self.n)]

    def combinations(self) -> Iterator[tuple[Any, ...]]:
        """Every combination of axis values, in walk order (grid product, then the random samples)."""
        samples = self.samples()
        for g in itertools.product(*(a.values for a in self.grid)):
            for s in samples:
                yield g + s

    def expand(self) -> list[Walk]:
        """Generate, hash and validate every walk (raises :class:`SweepError`)."""
        walks: list[Walk] = []
        seen: dict[str, int] = {}
        for i, combo in enumerate(self.combinations()):
            label = f"walk {i} (" + ", ".join(f"{a.column}={_short(v)}" for a, v in zip(self.axes, combo)) + ")"
            doc = copy.deepcopy(self.base_doc)
            for axis, value in zip(self.axes, combo):
                try:
                    axis.set_in(doc, value)
                except SweepError as exc:
                    raise SweepError(f"{self.source}: {axis.field}: {label}: {exc}") from None
            h = scenario_hash(doc)
            if h in seen:
                raise SweepError(f"{self.source}: {label} generates the same scenario as walk {seen[h]}: every walk "
                                 "must differ (check the grid and random values)")
            seen[h] = i
            try:
                parse_scenario(doc, f"{self.source}: {label}")
            except ScenarioError as exc:
                raise SweepError(str(exc)) from None
            params = {a.column: a.cell(v) for a, v in zip(self.axes, combo)}
            walks.append(Walk(i, params, doc, h, label))
        return walks


def _short(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    return _show(v, 40) if not isinstance(v, str) else v


# --------------------------------------------------------------------------------------------- reading
def _read_yaml(p: Path, what: str) -> Any:
    return read_yaml(p, what, SweepError)


def _resolve_base(src: Path, base: Any) -> Path:
    if not isinstance(base, str) or not base.strip():
        raise SweepError(f"{src}: base: expected the path of a scenario YAML file, got {_show(base)}")
    rel = Path(base)
    if rel.is_absolute():
        candidates = [rel]
    else:
        candidates = [src.parent / rel, Path.cwd() / rel]
    for c in candidates:
        if c.is_file():
            return c
    tried = " or ".join(str(c) for c in candidates)
    raise SweepError(f"{src}: base: no scenario file {base!r} (looked for {tried}; a relative path is taken "
                     "against the sweep file's folder, then the working directory)")


def _finite(src: Path, where: str, v: Any, what: str) -> float:
    if not _is_number(v) or not math.isfinite(float(v)):
        raise SweepError(f"{src}: {where}: expected {what}, got {_show(v)}")
    return float(v)


def _paths(src: Path, field: str, key: Any) -> tuple[DottedPath, ...]:
    if not isinstance(key, str) or not key.strip():
        raise SweepError(f"{src}: {field}: expected a dotted path into the scenario as the key, got {_show(key)}")
    return tuple(DottedPath.parse(part, f"{src}: {field}") for part in key.split(","))


def _grid_axis(src: Path, key: Any, raw: Any) -> Axis:
    field = f"grid.{key}"
    paths = _paths(src, field, key)
    expected = ("a non-empty list of values, or {scale: [factors]} to multiply the base value")
    if isinstance(raw, dict):
        if set(raw) != {"scale"}:
            bad = next((k for k in raw if k != "scale"), None)
            raise SweepError(f"{src}: {field}: {'unknown key ' + repr(bad) if bad is not None else 'empty mapping'}"
                             f"; expected {expected}")
        factors = raw["scale"]
        if not isinstance(factors, list) or not factors:
            raise SweepError(f"{src}: {field}.scale: expected a non-empty list of factors, got {_show(factors)}")
        values = tuple(_finite(src, f"{field}.scale[{i}]", f, "a finite number (a factor)")
                       for i, f in enumerate(factors))
        mode = "scale"
    elif isinstance(raw, list) and raw:
        values, mode = tuple(raw), "set"
    else:
        raise SweepError(f"{src}: {field}: expected {expected}, got {_show(raw)}")
    seen: dict[str, int] = {}
    for i, v in enumerate(values):
        k = json.dumps(_canonical(v), sort_keys=True, default=str)
        if k in seen:
            raise SweepError(f"{src}: {field}: the value {_show(v)} appears twice (entries {seen[k]} and {i})")
        seen[k] = i
    return Axis(field, paths, mode, values=values)


def _random_axis(src: Path, key: Any, raw: Any) -> Axis:
    field = f"random.{key}"
    paths = _paths(src, field, key)
    mode = "set"
    inner = raw
    if isinstance(raw, dict) and set(raw) == {"scale"}:
        mode, inner, field_in = "scale", raw["scale"], f"{field}.scale"
    else:
        field_in = field
    if not isinstance(inner, dict) or set(inner) != {"low", "high"}:
        raise SweepError(f"{src}: {field_in}: expected {{low: number, high: number}} (or {{scale: {{low, high}}}} for "
                         f"a factor), got {_show(raw)}")
    low = _finite(src, f"{field_in}.low", inner["low"], "a finite number")
    high = _finite(src, f"{field_in}.high", inner["high"], "a finite number")
    if not low < high:
        raise SweepError(f"{src}: {field_in}: expected low < high, got low = {low:g}, high = {high:g}")
    return Axis(field, paths, mode, low=low, high=high)


def _int(src: Path, where: str, v: Any, lo: int) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v < lo:
        raise SweepError(f"{src}: {where}: expected an integer >= {lo}, got {_show(v)}")
    return v


def parse_sweep(doc: Any, source: str | Path) -> SweepSpec:
    """Validate a parsed sweep document (raises :class:`SweepError`); ``source`` is the sweep file's path (the
    base scenario is resolved against its folder)."""
    src = Path(source)
    if doc is None:
        raise SweepError(f"{src}: the file is empty; expected a mapping with 'base' and 'grid' and/or 'random'")
    if not isinstance(doc, dict):
        raise SweepError(f"{src}: expected a mapping with keys {', '.join(TOP_KEYS)}, got {_show(doc)}")
    for k in doc:
        if k not in TOP_KEYS:
            raise SweepError(f"{src}: {k}: unknown key{suggest_key(str(k), TOP_KEYS)}")
    if "base" not in doc:
        raise SweepError(f"{src}: base: missing (expected the path of the base scenario YAML)")
    desc = doc.get("description", "")
    if not isinstance(desc, str):
        raise SweepError(f"{src}: description: expected a string, got {_show(desc)}")
    base_path = _resolve_base(src, doc["base"])
    try:
        base_doc = read_scenario_doc(base_path)   # the base's own ``base:`` chain resolved
        parse_scenario(base_doc, str(base_path))
    except ScenarioError as exc:
        raise SweepError(f"{src}: base: the base scenario is invalid: {exc}") from None
    grid_raw = doc.get("grid")
    if grid_raw is None:
        grid_raw = {}
    if not isinstance(grid_raw, dict):
        raise SweepError(f"{src}: grid: expected a mapping of dotted paths to values, got {_show(grid_raw)}")
    grid = tuple(_grid_axis(src, k, v) for k, v in grid_raw.items())
    rnd: tuple[Axis, ...] = ()
    n, seed = 0, None
    if "random" in doc:
        r = doc["random"]
        if not isinstance(r, dict):
            raise SweepError(f"{src}: random: expected a mapping with n, seed and dotted paths -> {{low, high}}, "
                             f"got {_show(r)}")
        for k in RANDOM_KEYS:
            if k not in r:
                raise SweepError(f"{src}: random.{k}: missing (expected "
                                 f"{'the number of samples' if k == 'n' else 'the seed of the generator'}, an integer)")
        n = _int(src, "random.n", r["n"], 1)
        seed = _int(src, "random.seed", r["seed"], 0)
        rnd = tuple(_random_axis(src, k, v) for k, v in r.items() if k not in RANDOM_KEYS)
        if not rnd:
            raise SweepError(f"{src}: random: no parameter to sample (expected dotted paths -> {{low, high}} besides "
                             "n and seed)")
    if not grid and not rnd:
        raise SweepError(f"{src}: nothing to sweep: expected at least one parameter under grid or random")
    all_paths = [(a.field, p) for a in grid + rnd for p in a.paths]
    for (fa, pa), (fb, pb) in itertools.combinations(all_paths, 2):
        if pa.overlaps(pb):
            raise SweepError(f"{src}: {fb}: {pb.text} and {pa.text} ({fa}) address the same value; sweep each value "
                             "on one axis only")
    spec = SweepSpec(src, base_path, base_doc, desc, grid, rnd, n, seed)
    if spec.n_walks > MAX_WALKS:
        raise SweepError(f"{src}: the grid and random samples give {spec.n_walks} walks; expected at most {MAX_WALKS} "
                         "per sweep file (split the sweep)")
    return spec


def load_sweep(path: str | Path) -> SweepSpec:
    """Read and validate a sweep file (raises :class:`SweepError`)."""
    p = Path(path)
    return parse_sweep(_read_yaml(p, "sweep file"), p)
