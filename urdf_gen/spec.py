"""Parse and validate the robot body-parameter YAML (``models/thesis_humanoid.yaml``).

Units are SI (m, kg, kg m^2, N m).  Every vector is resolved in the thesis frame of the body that owns it, with
its origin at the body's thesis origin O_k.  Vector entries in the YAML are numbers or names of ``dimensions``
entries, optionally negated (``-l3z``), so each measured length is written once.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

AXES = {"x": np.array([1.0, 0.0, 0.0]), "y": np.array([0.0, 1.0, 0.0]), "z": np.array([0.0, 0.0, 1.0])}


class SpecError(ValueError):
    """Invalid robot description; the message names the body/joint, the field and the value."""


@dataclass(frozen=True)
class BodySpec:
    """One thesis body (real or virtual).

    Attributes:
        id: thesis body number k.
        name: link name in the URDF.
        virtual: massless, dimensionless intermediate body of a multi-DOF joint.
        mass: kg (0 for virtual bodies).
        inertia: 3x3 inertia about the CoM, resolved in body frame k, kg m^2.
        com: c_k, vector O_k -> CoM, body frame, m.
        points: thesis vectors l_{k,z} from O_k to named points (O_z, toe points), body frame, m.
        joint_at: name of the point where the joint towards the tree root sits (``O_k`` = the origin itself).
        visual: raw visual description (viewer only).
    """

    id: int
    name: str
    virtual: bool
    mass: float
    inertia: np.ndarray
    com: np.ndarray
    points: dict[str, np.ndarray]
    joint_at: str
    visual: dict[str, Any] | None = None

    @property
    def origin_name(self) -> str:
        return f"O_{self.id}"

    def point(self, name: str) -> np.ndarray:
        """Position of a named point of this body relative to O_k, body frame (m)."""
        if name == self.origin_name:
            return np.zeros(3)
        if name in self.points:
            return self.points[name]
        raise SpecError(f"body {self.name} (id {self.id}): unknown point {name!r}; "
                        f"expected one of {[self.origin_name, *self.points]}")

    @property
    def link_offset(self) -> np.ndarray:
        """Position of the URDF link frame (the joint point) relative to O_k, body frame (m)."""
        return self.point(self.joint_at)


@dataclass(frozen=True)
class JointSpec:
    """One revolute joint of the tree rooted at the lower trunk.

    The pinocchio/URDF coordinate is ``q = sign * theta`` about the positive ``axis`` of the parent link frame.
    """

    theta: str
    parent: str
    child: str
    at: str
    axis: str
    sign: int
    actuator: str
    source: str = ""

    @property
    def axis_vector(self) -> np.ndarray:
        return AXES[self.axis]


@dataclass(frozen=True)
class RobotSpec:
    """The whole robot: bodies by thesis id, joints in tree order, actuator groups and global constants."""

    name: str
    bodies: dict[int, BodySpec]
    joints: list[JointSpec]
    theta_order: list[str]
    actuators: dict[str, dict[str, Any]]
    dims: dict[str, float]
    gravity: float
    C0: np.ndarray
    foot_sole: dict[str, float]
    root: str = "lower_trunk"
    raw: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    def body(self, name: str) -> BodySpec:
        for b in self.bodies.values():
            if b.name == name:
                return b
        raise SpecError(f"unknown body name {name!r}")

    @property
    def total_mass(self) -> float:
        return float(sum(b.mass for b in self.bodies.values()))


def _value(entry: Any) -> Any:
    return entry["value"] if isinstance(entry, dict) and "value" in entry else entry


def _resolve_vector(raw: Any, dims: dict[str, float], where: str) -> np.ndarray:
    raw = _value(raw)
    if not isinstance(raw, list) or len(raw) != 3:
        raise SpecError(f"{where}: expected a 3-vector, got {raw!r}")
    out = np.zeros(3)
    for i, item in enumerate(raw):
        if isinstance(item, bool):
            raise SpecError(f"{where}[{i}]: expected a number or a dimension name, got {item!r}")
        if isinstance(item, (int, float)):
            out[i] = float(item)
            continue
        if isinstance(item, str):
            sign, name = (-1.0, item[1:]) if item.startswith("-") else (1.0, item)
            if name not in dims:
                raise SpecError(f"{where}[{i}]: unknown dimension {name!r}; known: {sorted(dims)}")
            out[i] = sign * dims[name]
            continue
        raise SpecError(f"{where}[{i}]: expected a number or a dimension name, got {item!r}")
    return out


def _inertia_matrix(raw: Any, where: str) -> np.ndarray:
    """[Jxx Jyy Jzz Jxy Jxz Jyz] -> symmetric 3x3 (entries used as printed in the thesis, errata P-6)."""
    v = _value(raw)
    if not isinstance(v, list) or len(v) != 6 or not all(isinstance(x, (int, float)) for x in v):
        raise SpecError(f"{where}: expected [Jxx, Jyy, Jzz, Jxy, Jxz, Jyz] (6 numbers), got {v!r}")
    jxx, jyy, jzz, jxy, jxz, jyz = (float(x) for x in v)
    return np.array([[jxx, jxy, jxz], [jxy, jyy, jyz], [jxz, jyz, jzz]])


def validate_inertia(name: str, mass: float, inertia: np.ndarray) -> None:
    """Reject a non-physical mass/inertia: negative mass, not positive definite, triangle inequality violated."""
    if not np.isfinite(mass) or mass <= 0.0:
        raise SpecError(f"body {name}: mass must be a positive number of kg, got {mass!r}")
    if not np.all(np.isfinite(inertia)):
        raise SpecError(f"body {name}: inertia has non-finite entries {inertia.tolist()}")
    eig = np.linalg.eigvalsh(inertia)
    if eig[0] <= 0.0:
        raise SpecError(f"body {name}: inertia is not positive definite (principal moments {eig.tolist()} kg m^2)")
    # Principal moments of a real mass distribution satisfy I_a <= I_b + I_c for every permutation.
    tol = 1e-12 * float(eig.sum())
    for a in range(3):
        others = eig.sum() - eig[a]
        if eig[a] > others + tol:
            raise SpecError(
                f"body {name}: inertia violates the triangle inequality: principal moment {eig[a]:.6g} > "
                f"sum of the other two {others:.6g} kg m^2 (principal moments {eig.tolist()})")


def parse_spec(doc: dict[str, Any], source: str = "<yaml>") -> RobotSpec:
    """Build and validate a :class:`RobotSpec` from the parsed YAML document."""
    if not isinstance(doc, dict):
        raise SpecError(f"{source}: expected a mapping at the top level, got {type(doc).__name__}")
    for key in ("dimensions", "bodies", "joints", "theta_order", "actuators", "gravity", "initial_orientation"):
        if key not in doc:
            raise SpecError(f"{source}: missing top-level key {key!r}")
    dims = {}
    for k, v in doc["dimensions"].items():
        val = _value(v)
        if not isinstance(val, (int, float)) or isinstance(val, bool) or not np.isfinite(val) or val < 0:
            raise SpecError(f"{source}: dimensions.{k}: expected a non-negative length in m, got {val!r}")
        dims[k] = float(val)

    bodies: dict[int, BodySpec] = {}
    names: set[str] = set()
    for i, b in enumerate(doc["bodies"]):
        where = f"{source}: bodies[{i}]"
        if "id" not in b or "name" not in b:
            raise SpecError(f"{where}: every body needs 'id' and 'name', got keys {sorted(b)}")
        bid, name = int(b["id"]), str(b["name"])
        where = f"{source}: body {name} (id {bid})"
        if name in names:
            raise SpecError(f"{where}: duplicate body name {name!r}")
        if bid in bodies:
            raise SpecError(f"{where}: duplicate body id {bid}")
        names.add(name)
        virtual = bool(b.get("virtual", False))
        if virtual:
            mass, inertia, com, points = 0.0, np.zeros((3, 3)), np.zeros(3), {}
        else:
            mass = _value(b.get("mass"))
            if isinstance(mass, bool) or not isinstance(mass, (int, float)):
                raise SpecError(f"{where}: mass must be a number of kg, got {mass!r}")
            mass = float(mass)
            inertia = _inertia_matrix(b.get("inertia"), f"{where}: inertia")
            validate_inertia(name, mass, inertia)
            com = _resolve_vector(b.get("com"), dims, f"{where}: com")
            points = {str(k): _resolve_vector(v, dims, f"{where}: points.{k}")
                      for k, v in (b.get("points") or {}).items()}
        body = BodySpec(id=bid, name=name, virtual=virtual, mass=mass, inertia=inertia, com=com, points=points,
                        joint_at=str(b.get("joint_at", f"O_{bid}")), visual=b.get("visual"))
        _ = body.link_offset  # validates joint_at
        bodies[bid] = body

    by_name = {b.name: b for b in bodies.values()}
    root = "lower_trunk"
    if root not in by_name:
        raise SpecError(f"{source}: the tree root body {root!r} is missing")

    joints: list[JointSpec] = []
    seen_children: set[str] = {root}
    thetas: set[str] = set()
    for i, j in enumerate(doc["joints"]):
        where = f"{source}: joints[{i}] ({j.get('theta', '?')})"
        for key in ("theta", "parent", "child", "at", "axis", "sign", "actuator"):
            if key not in j:
                raise SpecError(f"{where}: missing field {key!r}")
        if j["parent"] not in by_name:
            raise SpecError(f"{where}: unknown parent {j['parent']!r}")
        if j["child"] not in by_name:
            raise SpecError(f"{where}: unknown child {j['child']!r}")
        if j["parent"] not in seen_children:
            raise SpecError(f"{where}: parent {j['parent']!r} is not yet connected to the root "
                            "(joints must be listed in tree order)")
        if j["child"] in seen_children:
            raise SpecError(f"{where}: child {j['child']!r} already has a parent joint")
        if j["axis"] not in AXES:
            raise SpecError(f"{where}: axis must be one of x, y, z, got {j['axis']!r}")
        if j["sign"] not in (1, -1):
            raise SpecError(f"{where}: sign must be +1 or -1, got {j['sign']!r}")
        if j["theta"] in thetas:
            raise SpecError(f"{where}: duplicate joint variable {j['theta']!r}")
        if j["actuator"] not in doc["actuators"]:
            raise SpecError(f"{where}: unknown actuator group {j['actuator']!r}")
        by_name[j["parent"]].point(j["at"])  # validates the joint point
        seen_children.add(j["child"])
        thetas.add(j["theta"])
        joints.append(JointSpec(theta=str(j["theta"]), parent=str(j["parent"]), child=str(j["child"]),
                                at=str(j["at"]), axis=str(j["axis"]), sign=int(j["sign"]),
                                actuator=str(j["actuator"]), source=str(j.get("source", ""))))
    unattached = set(by_name) - seen_children
    if unattached:
        raise SpecError(f"{source}: bodies not connected to the root by any joint: {sorted(unattached)}")
    order = [str(t) for t in doc["theta_order"]]
    if sorted(order) != sorted(thetas) or len(order) != len(set(order)):
        raise SpecError(f"{source}: theta_order must list every joint variable once; got {order}, "
                        f"joints define {sorted(thetas)}")
    for k, a in doc["actuators"].items():
        lim = a.get("limit") if isinstance(a, dict) else None
        if isinstance(lim, bool) or not isinstance(lim, (int, float)) or lim <= 0:
            raise SpecError(f"{source}: actuators.{k}.limit: expected a positive torque in N m, got {lim!r}")
    C0 = np.array(_value(doc["initial_orientation"]), dtype=float)
    if C0.shape != (3, 3) or not np.allclose(C0 @ C0.T, np.eye(3), atol=1e-12) or np.linalg.det(C0) < 0:
        raise SpecError(f"{source}: initial_orientation must be a 3x3 rotation matrix, got {C0.tolist()}")
    sole = {k: float(_value(v)) for k, v in (doc.get("foot_sole") or {}).items()}
    return RobotSpec(name=str(doc.get("meta", {}).get("name", "robot")), bodies=bodies, joints=joints,
                     theta_order=order, actuators=dict(doc["actuators"]), dims=dims,
                     gravity=float(_value(doc["gravity"])), C0=C0, foot_sole=sole, root=root, raw=doc)


def load_spec(path: str | Path) -> RobotSpec:
    """Read and validate a robot YAML file."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise SpecError(f"{path}: cannot read: {exc.strerror}") from exc
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise SpecError(f"{path}: not valid YAML: {exc}") from exc
    return parse_spec(doc, str(path))
