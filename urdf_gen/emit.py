"""Render a :class:`~urdf_gen.spec.RobotSpec` as URDF text (deterministic: same spec, same bytes).

URDF layout (design.md section 3):
- one link per thesis body, real or virtual, named as in the YAML; the link frame sits at the body's joint
  towards the lower trunk (hip at O_11, knee at O_9, ankle at O_3, toe at O_1, waist at O_17, shoulders at
  O_21/O_22, neck at O_20) with the thesis body-frame orientation, so every joint origin has rpy = 0;
- 26 revolute joints named after the thesis variable (``theta3`` ... ``theta27``), axis = + unit axis,
  coordinate q = sign * theta, effort limit = the actuator group's saturation (errata section 7);
- named frames as massless links on fixed joints: ``O_k`` for every thesis body frame, ``Pc_k`` for every
  real body's centre of mass, ``P_tpR``/``P_tpL`` for the toe points.
Joints carry position limits of +-pi only because URDF requires them for revolute joints; the thesis joints
can turn fully (chapter 2, L760) and nothing in the simulator enforces these limits.
"""

from __future__ import annotations

import math

import numpy as np

from urdf_gen.spec import BodySpec, RobotSpec

MATERIALS = {
    "right": (0.80, 0.25, 0.20, 1.0),
    "left": (0.20, 0.40, 0.85, 1.0),
    "centre": (0.70, 0.70, 0.70, 1.0),
}
JOINT_VELOCITY_LIMIT = 100.0  # rad/s, URDF needs a value; the thesis sets none


def _num(x: float) -> str:
    """Format a float compactly and deterministically (no '-0')."""
    x = float(x)
    if abs(x) < 1e-15:
        return "0"
    return f"{x:.12g}"


def _vec(v) -> str:
    return " ".join(_num(x) for x in v)


def _side(name: str) -> str:
    if name.startswith("right"):
        return "right"
    if name.startswith("left"):
        return "left"
    return "centre"


def _rpy_z_to(d: np.ndarray) -> np.ndarray:
    """Roll-pitch-yaw of a rotation taking +z onto the unit vector d (for cylinder visuals)."""
    d = d / np.linalg.norm(d)
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, d)
    s, c = np.linalg.norm(axis), float(z @ d)
    if s < 1e-12:
        R = np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    else:
        k = axis / s
        K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        R = np.eye(3) + s * K + (1 - c) * K @ K
    # URDF rpy: R = Rz(yaw) Ry(pitch) Rx(roll)
    pitch = math.asin(max(-1.0, min(1.0, -R[2, 0])))
    roll = math.atan2(R[2, 1], R[2, 2])
    yaw = math.atan2(R[1, 0], R[0, 0])
    return np.array([roll, pitch, yaw])


def _resolve(body: BodySpec, item, dims: dict[str, float]) -> np.ndarray:
    """A visual point: a named point of the body, or a vector of numbers/dimension names (body frame)."""
    if isinstance(item, str):
        return body.point(item)
    out = []
    for x in item:
        if isinstance(x, str):
            out.append(-dims[x[1:]] if x.startswith("-") else dims[x])
        else:
            out.append(float(x))
    return np.array(out)


def _visual(body: BodySpec, spec: RobotSpec) -> list[str]:
    vis = body.visual
    if not vis:
        return []
    off = body.link_offset
    mat = _side(body.name)
    shape = vis["shape"]
    if shape == "box":
        centre = _resolve(body, vis["center"], spec.dims) - off
        geom = f'<box size="{_vec(vis["size"])}"/>'
        rpy = np.zeros(3)
    elif shape == "sphere":
        centre = _resolve(body, vis["center"], spec.dims) - off
        geom = f'<sphere radius="{_num(vis["radius"])}"/>'
        rpy = np.zeros(3)
    elif shape == "cylinder":
        a = _resolve(body, vis["from"], spec.dims) - off
        b = _resolve(body, vis["to"], spec.dims) - off
        centre = 0.5 * (a + b)
        geom = f'<cylinder radius="{_num(vis["radius"])}" length="{_num(np.linalg.norm(b - a))}"/>'
        rpy = _rpy_z_to(b - a)
    else:
        raise ValueError(f"body {body.name}: unknown visual shape {shape!r}")
    return [
        "    <visual>",
        f'      <origin xyz="{_vec(centre)}" rpy="{_vec(rpy)}"/>',
        f"      <geometry>{geom}</geometry>",
        f'      <material name="{mat}"/>',
        "    </visual>",
    ]


def _link(body: BodySpec, spec: RobotSpec) -> list[str]:
    lines = [f'  <link name="{body.name}">']
    if not body.virtual:
        J = body.inertia
        lines += [
            "    <inertial>",
            f'      <origin xyz="{_vec(body.com - body.link_offset)}" rpy="0 0 0"/>',
            f'      <mass value="{_num(body.mass)}"/>',
            f'      <inertia ixx="{_num(J[0, 0])}" ixy="{_num(J[0, 1])}" ixz="{_num(J[0, 2])}" '
            f'iyy="{_num(J[1, 1])}" iyz="{_num(J[1, 2])}" izz="{_num(J[2, 2])}"/>',
            "    </inertial>",
        ]
    lines += _visual(body, spec)
    lines.append("  </link>")
    return lines


def _frame(name: str, parent: str, xyz: np.ndarray) -> list[str]:
    return [
        f'  <link name="{name}"/>',
        f'  <joint name="{name}_fixed" type="fixed">',
        f'    <parent link="{parent}"/>',
        f'    <child link="{name}"/>',
        f'    <origin xyz="{_vec(xyz)}" rpy="0 0 0"/>',
        "  </joint>",
    ]


def emit_urdf(spec: RobotSpec, source_note: str = "") -> str:
    """Return the URDF document for ``spec`` as a string."""
    by_name = {b.name: b for b in spec.bodies.values()}
    out = ['<?xml version="1.0"?>',
           "<!-- Generated by urdf_gen from the thesis body data. Do not edit: regenerate with",
           "     python -m urdf_gen models/thesis_humanoid.yaml -o models/thesis_humanoid.urdf -->"]
    if source_note:
        out.append(f"<!-- {source_note} -->")
    out.append(f'<robot name="{spec.name}">')
    for mat, rgba in MATERIALS.items():
        out.append(f'  <material name="{mat}"><color rgba="{_vec(rgba)}"/></material>')
    order = [spec.root] + [j.child for j in spec.joints]
    for name in order:
        out += _link(by_name[name], spec)
    for j in spec.joints:
        parent, child = by_name[j.parent], by_name[j.child]
        xyz = parent.point(j.at) - parent.link_offset
        limit = float(spec.actuators[j.actuator]["limit"])
        out += [
            f'  <joint name="{j.theta}" type="revolute">',
            f"    <!-- thesis {j.theta} = {j.sign:+d} * q; {j.source} -->",
            f'    <parent link="{parent.name}"/>',
            f'    <child link="{child.name}"/>',
            f'    <origin xyz="{_vec(xyz)}" rpy="0 0 0"/>',
            f'    <axis xyz="{_vec(j.axis_vector)}"/>',
            f'    <limit lower="{_num(-math.pi)}" upper="{_num(math.pi)}" effort="{_num(limit)}" '
            f'velocity="{_num(JOINT_VELOCITY_LIMIT)}"/>',
            "  </joint>",
        ]
    # Named frames: thesis body origins O_k, centres of mass Pc_k and the toe points.
    for name in order:
        body = by_name[name]
        out += _frame(body.origin_name, body.name, -body.link_offset)
        if not body.virtual:
            out += _frame(f"Pc_{body.id}", body.name, body.com - body.link_offset)
        for pname, p in body.points.items():
            if pname.startswith("P_tp"):
                out += _frame(pname, body.name, p - body.link_offset)
    out.append("</robot>")
    return "\n".join(out) + "\n"
