"""The robot as a design variable: a variant of the thesis body table, its generated URDF and its model.

A :class:`RobotVariant` changes the body table ``models/thesis_humanoid.yaml`` (the thesis's Tables 2.3-2.5):

- **length scales** per segment (:data:`SEGMENTS`): the segment's lengths along its long axis (the thesis
  dimensions it owns, e.g. the shank's ``l9`` and ``c9``) are multiplied by the factor.  Every joint point and
  centre of mass written with those dimensions moves with them, and so do the sole (the foot) and the viewer's
  geometry.
- **mass scales** per body, segment or ``all`` (the factors multiply: ``all`` x segment x body).
- **the sole's** length (the heel moves, the toe tip stays) and width.
- **a payload**: a point mass at a given place on a trunk body.

How a body's inertia follows (the thesis's own shapes): the body's mass distribution is stretched along the
segment's axis and its density scaled, so its second moments about the CoM ``Sigma = tr(I)/2 1 - I`` become
``s_m S Sigma S`` with ``S = diag`` (the length factor on the axis, 1 across), and ``I' = tr(Sigma') 1 - Sigma'``.
This is exact for any shape stretched along one axis (a cylinder, a box, the thesis's tabulated bodies alike),
keeps the inertia physical, and with factor 1 gives the thesis's numbers back.  A payload adds its point mass
by the parallel-axis theorem about the body's new CoM.

:func:`variant_model` writes the variant's body table and URDF once into the cache folder
(:func:`humanoid_sim.paths.cache_dir`), named by the hash of the variant's parameters and of the base body table,
and loads the model from there; the nominal variant is the shipped model itself, bit for bit.
Units: SI (m, kg, kg m^2).  Vectors are in the body's thesis frame, from its origin O_k.
"""

from __future__ import annotations

import copy
import hashlib
import json
import os
import tempfile
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from humanoid_sim.paths import cache_dir
from humanoid_sim.robot.model import DEFAULT_SPEC, DEFAULT_URDF, HumanoidModel, ModelError, load_model
from urdf_gen.emit import emit_urdf
from urdf_gen.spec import parse_spec


@dataclass(frozen=True)
class Segment:
    """A segment of the body table that a length scale stretches.

    Attributes:
        bodies: thesis body ids of the segment (both sides).
        dims: the body table's dimensions along the segment's axis (lengths and CoM distances).
        axis: the long axis in the bodies' frames (0 = x, 2 = z).
    """

    bodies: tuple[int, ...]
    dims: tuple[str, ...]
    axis: int


SEGMENTS: dict[str, Segment] = {
    "foot": Segment((1, 2, 3, 4), ("l1", "c1", "l3x", "c3x"), 0),   # toe and main body, heel to toe tip (x)
    "shank": Segment((9, 10), ("l9", "c9"), 2),
    "thigh": Segment((11, 12), ("l11", "c11"), 2),
    "trunk": Segment((17, 20), ("l17z", "c17", "l20z", "c20"), 2),
    "arms": Segment((23, 24), ("l23z", "c23"), 2),
    "head": Segment((27,), ("l27", "c27"), 2),
}
"""Segment name -> the bodies and dimensions a length scale stretches."""

MASS_GROUPS: dict[str, tuple[int, ...]] = {
    **{name: seg.bodies for name, seg in SEGMENTS.items()},
    "toe": (1, 2), "lower_trunk": (17,), "upper_trunk": (20,),
}
"""Mass-scale keys besides ``all`` and the body names: segment -> body ids."""

PAYLOAD_BODIES = ("lower_trunk", "upper_trunk")
"""The bodies a payload may sit on."""


@dataclass(frozen=True)
class Payload:
    """A point mass carried on a trunk body.

    Attributes:
        mass_kg: kg (>= 0).
        body: ``upper_trunk`` (body 20) or ``lower_trunk`` (body 17).
        position_m: from the body's thesis origin O_k, in its frame, m; None = at the body's CoM.
    """

    mass_kg: float
    body: str = "upper_trunk"
    position_m: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class RobotVariant:
    """Parameters of a robot variant (module docstring); every default is the thesis robot.

    Attributes:
        length_scale: segment name (:data:`SEGMENTS`) -> factor, sorted by name.
        mass_scale: ``all``, a segment (:data:`MASS_GROUPS`) or a body name -> factor, sorted by name.
        sole_length_m: the sole's length heel to toe tip, m; None = the foot's (scaled) own.
        sole_width_m: the sole's width, m; None = the body table's.
        payload: a point mass on the trunk, or None.
    """

    length_scale: tuple[tuple[str, float], ...] = ()
    mass_scale: tuple[tuple[str, float], ...] = ()
    sole_length_m: float | None = None
    sole_width_m: float | None = None
    payload: Payload | None = None
    base: Path = field(default=DEFAULT_SPEC, compare=False)

    @property
    def is_nominal(self) -> bool:
        """True when the variant is the body table itself (every factor 1, no sole change, no payload mass)."""
        return (all(f == 1.0 for _, f in self.length_scale) and all(f == 1.0 for _, f in self.mass_scale)
                and self.sole_length_m is None and self.sole_width_m is None
                and (self.payload is None or self.payload.mass_kg == 0.0))

    def parameters(self) -> dict[str, Any]:
        """The parameters as plain data (for the summary, the hash and the written body table)."""
        p = self.payload
        return {"length_scale": dict(self.length_scale), "mass_scale": dict(self.mass_scale),
                "sole_length_m": self.sole_length_m, "sole_width_m": self.sole_width_m,
                "payload": None if p is None else {"mass_kg": p.mass_kg, "body": p.body,
                                                   "position_m": None if p.position_m is None
                                                   else list(p.position_m)}}

    def hip_height_change(self) -> float:
        """How much higher the lower trunk's CoM (frame Pc_17, the path's hip point) stands above the ankles at the
        same joint angles, m: the shank's and thigh's length changes plus that of the lower trunk's CoM above its
        hip joints (``l17z - c17``, with the trunk's factor)."""
        d = {k: float(_value(v)) for k, v in _table(self.base)[1]["dimensions"].items()}
        f = dict(self.length_scale)
        return (d["l9"] * (f.get("shank", 1.0) - 1.0) + d["l11"] * (f.get("thigh", 1.0) - 1.0)
                + (d["l17z"] - d["c17"]) * (f.get("trunk", 1.0) - 1.0))

    def key(self) -> str:
        """Hash of the parameters and of the base body table's text (16 hex digits): the cache's file name."""
        text = json.dumps(self.parameters(), sort_keys=True, separators=(",", ":"))
        h = hashlib.sha256(text.encode())
        h.update(_table(self.base)[0])
        return h.hexdigest()[:16]


def _table(path: Path) -> tuple[bytes, dict[str, Any]]:
    """The body table's bytes and parsed document, read once per process and file version (every scenario with a
    ``robot`` section asks for them; callers must not change the document)."""
    path = Path(path)
    return _read_table(path, path.stat().st_mtime_ns)


@lru_cache(maxsize=4)
def _read_table(path: Path, mtime_ns: int) -> tuple[bytes, dict[str, Any]]:
    data = path.read_bytes()
    return data, yaml.safe_load(data)


class VariantError(ModelError):
    """A variant the body table cannot take (the message names the parameter and the value)."""


def _inertia(v: list[float]) -> np.ndarray:
    jxx, jyy, jzz, jxy, jxz, jyz = (float(x) for x in v)
    return np.array([[jxx, jxy, jxz], [jxy, jyy, jyz], [jxz, jyz, jzz]])


def _inertia_list(I: np.ndarray) -> list[float]:
    return [float(I[0, 0]), float(I[1, 1]), float(I[2, 2]), float(I[0, 1]), float(I[0, 2]), float(I[1, 2])]


def stretched_inertia(I: np.ndarray, mass_factor: float, stretch: np.ndarray) -> np.ndarray:
    """Inertia about the CoM of a body whose mass is scaled by ``mass_factor`` and whose shape is stretched by
    ``stretch`` (3,) along its frame's axes (module docstring), kg m^2."""
    sigma = 0.5 * np.trace(I) * np.eye(3) - I
    S = np.diag(stretch)
    sig = mass_factor * S @ sigma @ S
    return np.trace(sig) * np.eye(3) - sig


def _value(entry: Any) -> Any:
    return entry["value"] if isinstance(entry, dict) and "value" in entry else entry


def _scaled_entry(entry: Any, factor: float, note: str) -> dict[str, Any]:
    value = _value(entry)
    src = entry.get("source", "") if isinstance(entry, dict) else ""
    return {"value": float(value) * factor, "source": f"{src}; x {factor:g} ({note})".lstrip("; ")}


def _scale_visual(visual: dict[str, Any] | None, stretch: np.ndarray) -> dict[str, Any] | None:
    """The viewer geometry stretched alike (numbers only: named points follow their dimensions)."""
    if visual is None:
        return None
    out = dict(visual)
    for key in ("center", "size"):
        if key in out and isinstance(out[key], list):
            out[key] = [float(x * s) if isinstance(x, (int, float)) else x for x, s in zip(out[key], stretch)]
    return out


def variant_doc(base_doc: dict[str, Any], variant: RobotVariant) -> dict[str, Any]:
    """The body table of ``variant``: a copy of ``base_doc`` (the parsed YAML) with its dimensions, masses,
    inertias, sole and viewer geometry changed (module docstring).

    Raises:
        VariantError: an unknown segment or body, or a sole the foot cannot carry.
    """
    doc = copy.deepcopy(base_doc)
    lengths = dict(variant.length_scale)
    for name, f in lengths.items():
        if name not in SEGMENTS:
            raise VariantError(f"length_scale.{name}: unknown segment; expected one of {', '.join(SEGMENTS)}")
        for d in SEGMENTS[name].dims:
            doc["dimensions"][d] = _scaled_entry(doc["dimensions"][d], f, f"robot.length_scale.{name}")
    stretch_of: dict[int, np.ndarray] = {}
    for name, f in lengths.items():
        seg = SEGMENTS[name]
        for b in seg.bodies:
            s = np.ones(3)
            s[seg.axis] = f
            stretch_of[b] = s
    body_names = {str(b["name"]): int(b["id"]) for b in doc["bodies"] if not b.get("virtual")}
    mass_of: dict[int, float] = dict.fromkeys(body_names.values(), 1.0)
    for key, f in variant.mass_scale:
        if key == "all":
            ids: tuple[int, ...] = tuple(mass_of)
        elif key in MASS_GROUPS:
            ids = MASS_GROUPS[key]
        elif key in body_names:
            ids = (body_names[key],)
        else:
            raise VariantError(f"mass_scale.{key}: not a body; expected all, a segment "
                               f"({', '.join(MASS_GROUPS)}) or a body ({', '.join(body_names)})")
        for b in ids:
            mass_of[b] *= f
    for b in doc["bodies"]:
        if b.get("virtual"):
            continue
        bid = int(b["id"])
        mf, st = mass_of[bid], stretch_of.get(bid, np.ones(3))
        if mf == 1.0 and np.all(st == 1.0):
            continue
        b["mass"] = _scaled_entry(b["mass"], mf, "robot.mass_scale")
        I = stretched_inertia(_inertia(_value(b["inertia"])), mf, st)
        b["inertia"] = {"value": _inertia_list(I), "source": "the body table's, stretched and scaled (robot.variant)"}
        b["visual"] = _scale_visual(b.get("visual"), st)
    _sole(doc, variant, lengths.get("foot", 1.0))
    if variant.payload is not None and variant.payload.mass_kg > 0.0:
        _add_payload(doc, variant.payload)
    doc.setdefault("meta", {})["name"] = f"{doc.get('meta', {}).get('name', 'robot')}_{variant.key()}"
    doc["meta"]["variant"] = variant.parameters()
    return doc


def check_sole_length(length_m: float, foot_scale: float = 1.0, base: Path = DEFAULT_SPEC) -> None:
    """Refuse a sole that does not reach behind the toe body (the heel box runs from the heel to the toe joint).

    Args:
        length_m: the sole's length, heel to toe tip, m.
        foot_scale: the foot's length factor.
        base: the body table.

    Raises:
        VariantError: the sole is not longer than the toe body plus 0.01 m.
    """
    toe = float(_value(_table(base)[1]["dimensions"]["l1"])) * foot_scale
    if length_m <= toe + 0.01:
        raise VariantError(f"length_m = {length_m:g}: expected more than the toe body's length {toe:.4g} m + 0.01 m "
                           "(the heel box runs from the heel to the toe joint)")


def _sole(doc: dict[str, Any], variant: RobotVariant, foot: float) -> None:
    sole = doc["foot_sole"]
    if foot != 1.0:
        for k in ("length", "toe_front_x", "heel_back_x"):
            sole[k] = _scaled_entry(sole[k], foot, "robot.length_scale.foot")
    front = float(_value(sole["toe_front_x"]))
    if variant.sole_length_m is not None:
        check_sole_length(variant.sole_length_m, foot, variant.base)
        sole["length"] = {"value": variant.sole_length_m, "source": "robot.sole_length_m"}
        sole["heel_back_x"] = {"value": front - variant.sole_length_m, "source": "toe_front_x - robot.sole_length_m"}
    if variant.sole_width_m is not None:
        sole["width"] = {"value": variant.sole_width_m, "source": "robot.sole_width_m"}
    if foot != 1.0 or variant.sole_length_m is not None or variant.sole_width_m is not None:
        _foot_boxes(doc)


def _foot_boxes(doc: dict[str, Any]) -> None:
    """Rebuild the feet's boxes from the sole: the main body's from the heel to the toe joint (x = l3x), the toe
    body's from the toe joint to the toe tip, the sole's width; their heights as they were.  The MuJoCo engine
    takes these boxes as the feet's collision geometry and checks their bottoms against the sole."""
    sole = {k: float(_value(v)) for k, v in doc["foot_sole"].items()}
    joint_x = float(_value(doc["dimensions"]["l3x"]))
    spans = {3: (sole["heel_back_x"], joint_x), 4: (sole["heel_back_x"], joint_x),
             1: (0.0, sole["toe_front_x"] - joint_x), 2: (0.0, sole["toe_front_x"] - joint_x)}
    for b in doc["bodies"]:
        bid = int(b["id"])
        if bid in spans and isinstance(b.get("visual"), dict) and b["visual"].get("shape") == "box":
            lo, hi = spans[bid]
            vis = b["visual"]
            b["visual"] = {**vis, "center": [0.5 * (lo + hi), vis["center"][1], vis["center"][2]],
                           "size": [hi - lo, sole["width"], vis["size"][2]]}


def _add_payload(doc: dict[str, Any], payload: Payload) -> None:
    """Merge the point mass into its body (parallel-axis theorem about the combined CoM)."""
    spec = parse_spec(doc, "<robot variant>")
    body = spec.body(payload.body)
    entry = next(b for b in doc["bodies"] if b["name"] == payload.body)
    m, c = body.mass, body.com
    p = c if payload.position_m is None else np.asarray(payload.position_m, dtype=float)
    mp = payload.mass_kg
    c_new = (m * c + mp * p) / (m + mp)

    def shift(mass: float, r: np.ndarray) -> np.ndarray:   # point-mass inertia about a point at -r
        return mass * (float(r @ r) * np.eye(3) - np.outer(r, r))

    I = body.inertia + shift(m, c - c_new) + shift(mp, p - c_new)
    entry["mass"] = {"value": m + mp, "source": f"{m:.6g} kg + payload {mp:g} kg (robot.payload)"}
    entry["com"] = {"value": [float(x) for x in c_new], "source": "the body's and the payload's combined CoM"}
    entry["inertia"] = {"value": _inertia_list(I), "source": "the body's and the payload's, about the combined CoM"}


def _write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename, so that parallel walks never read a
    half-written file."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", newline="\n") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def variant_files(variant: RobotVariant, folder: Path | None = None) -> tuple[Path, Path]:
    """The variant's body table and URDF, written into ``folder`` (default: the cache's ``models``) unless there.

    Returns:
        (body-table YAML, URDF) paths; the shipped model's for a nominal variant.
    """
    if variant.is_nominal and folder is None:
        return DEFAULT_SPEC, DEFAULT_URDF
    folder = cache_dir() / "models" if folder is None else Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    name = f"robot_{variant.key()}"
    spec_path, urdf_path = folder / f"{name}.yaml", folder / f"{name}.urdf"
    if not (spec_path.is_file() and urdf_path.is_file()):
        doc = variant_doc(_table(variant.base)[1], variant)   # variant_doc changes a deep copy
        spec = parse_spec(doc, f"robot variant {name}")
        header = ("# A variant of the thesis humanoid's body table, written by humanoid_sim.robot.variant from\n"
                  f"# {Path(variant.base).name} and the parameters under meta.variant.\n")
        _write_atomic(spec_path, header + yaml.safe_dump(doc, sort_keys=False))
        _write_atomic(urdf_path, emit_urdf(spec, f"variant {name} of {Path(variant.base).name}"))
    return spec_path, urdf_path


def variant_model(variant: RobotVariant | None) -> HumanoidModel:
    """The model of ``variant`` (the shipped model for None or a nominal variant)."""
    if variant is None:
        return load_model()
    spec_path, urdf_path = variant_files(variant)
    return load_model(urdf_path, spec_path)


__all__ = ["MASS_GROUPS", "check_sole_length", "PAYLOAD_BODIES", "SEGMENTS", "Payload", "RobotVariant", "VariantError",
           "stretched_inertia", "variant_doc", "variant_files", "variant_model"]
