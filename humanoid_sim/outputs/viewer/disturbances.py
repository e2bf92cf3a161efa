"""A scenario's disturbances in the playback: the terrain boxes, and each push as an arrow while it acts.

Drawn only for a run with a ``disturbances`` section (its summary.json entry, :mod:`humanoid_sim.sim.disturbances`):
a run without one gets the scene it always had.

- ``disturbances/terrain/<i>``: each terrain box (world frame), sand coloured, at its place and rotation;
- ``disturbances/push/<i>``: each push as a red arrow whose head touches the pushed point (the push acts along
  it), length :data:`PUSH_SCALE` m per N, shown in the frames whose time lies in the push's window.
"""

from __future__ import annotations

from typing import Any

import meshcat
import meshcat.geometry as g
import numpy as np

from humanoid_sim.outputs.viewer.frames import PlaybackFrames, _homogeneous, _y_to

PUSH_SCALE = 4.0e-3
"""Push arrow length per newton, m/N (a 110 N push draws 0.44 m: four times the ground-reaction arrows' scale, so
a push of a fifth of the robot's weight reads next to them)."""
PUSH_HEX = 0xD62728
TERRAIN_HEX = 0xC8B07A
_SHAFT_RADIUS = 0.012   # m
_HEAD_LEN = 0.06        # m
_HEAD_RADIUS = 0.03     # m


def _point_frame(body: Any) -> str | None:
    """The model frame of a push's point: ``Pc_<n>`` for a thesis body number, the name of a frame, or None (a link:
    its centre of mass is drawn at the lower trunk's, the logged hip, when the link is not a frame)."""
    return f"Pc_{body}" if isinstance(body, int) else str(body)


def push_frames(fr: PlaybackFrames, results: dict[str, np.ndarray], hm: Any, entry: dict[str, Any]) -> None:
    """Add the push arrows' poses and visibility to ``fr`` (the frames of :func:`.frames.build_frames`).

    Args:
        fr: the playback frames.
        results: the run's log (its ``q``).
        hm: the robot (the pushed points' frames).
        entry: summary.json's ``disturbances`` entry.
    """
    import pinocchio as pin

    q = np.asarray(results["q"], dtype=float)[fr.step]
    t = np.asarray(fr.step_t, dtype=float)
    n = len(t)
    data = hm.model.createData()
    names = {f.name for f in hm.model.frames}
    for i, push in enumerate(entry.get("pushes") or []):
        F = push.get("force_world_N")
        if F is None:     # the run ended before the push
            continue
        F = np.asarray(F, dtype=float)
        on = (t >= push["start_s"] - 1e-9) & (t < push["start_s"] + push["duration_s"] - 1e-9)
        frame = _point_frame(push["body"])
        fid = hm.frame_id(frame if frame in names else "Pc_17")
        length = float(np.linalg.norm(F)) * PUSH_SCALE
        R = _y_to(F)
        T = np.repeat(np.eye(4)[None], n, axis=0)
        for j in np.flatnonzero(on):
            pin.forwardKinematics(hm.model, data, q[j])
            p = pin.updateFramePlacement(hm.model, data, fid).translation
            T[j] = _homogeneous(R, p - R[:, 1] * (length + _HEAD_LEN))   # the tail, so the head touches p
        path = f"disturbances/push/{i}"
        fr.transforms[path] = T
        fr.visible[path] = on
        shaft, head = np.eye(4), np.eye(4)
        shaft[1, 3] = length / 2
        head[1, 3] = length + _HEAD_LEN / 2
        fr.transforms[f"{path}/shaft"] = np.repeat(shaft[None], n, axis=0)
        fr.scales[f"{path}/shaft"] = np.tile([1.0, length, 1.0], (n, 1))
        fr.transforms[f"{path}/head"] = np.repeat(head[None], n, axis=0)


def add_objects(vis: meshcat.Visualizer, entry: dict[str, Any]) -> None:
    """Create the terrain boxes (posed: they do not move) and the push arrows' shapes (posed by the frames)."""
    box = g.MeshLambertMaterial(color=TERRAIN_HEX, opacity=1.0)
    for i, piece in enumerate(entry.get("terrain") or []):
        node = vis[f"disturbances/terrain/{i}"]
        node.set_object(g.Box([float(x) for x in piece["size_m"]]), box)
        node.set_transform(_homogeneous(np.asarray(piece["rotation"]), np.asarray(piece["centre_m"])))
    arrow = g.MeshLambertMaterial(color=PUSH_HEX, opacity=0.9, depthTest=False)
    for i, push in enumerate(entry.get("pushes") or []):
        if push.get("force_world_N") is None:
            continue
        vis[f"disturbances/push/{i}/shaft"].set_object(g.Cylinder(1.0, _SHAFT_RADIUS), arrow)
        vis[f"disturbances/push/{i}/head"].set_object(g.Cylinder(_HEAD_LEN, radiusTop=0.0,
                                                                 radiusBottom=_HEAD_RADIUS), arrow)


__all__ = ["PUSH_SCALE", "add_objects", "push_frames"]
