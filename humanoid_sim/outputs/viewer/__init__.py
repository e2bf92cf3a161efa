"""See a run in meshcat: live playback (:func:`play_live`) and an offline recording (:func:`write_playback`).

The scene (all coordinates in the world frame of design.md section 3: x lateral, y forward, z up, metres):

- ``robot/<body>``: the URDF's visual geometry (boxes, cylinders, a sphere) posed from the logged
  configuration ``q``; each part on one side in that side's colour (right green, left purple, as every figure's
  feet: :func:`humanoid_sim.outputs.colours.body_colour`), trunk and head grey.
- ``ground``: a 0.1 m grid on z = 0 around the walk, 1 m lines darker.
- ``reference/hip_<k>``: the planned Body-17 CoM path, one line per phase, in the thesis phase colours
  (LFFSSP red, RFFDSP blue, RFFSSP magenta, LFFDSP cyan); ``reference/toe_R`` / ``reference/toe_L``: the planned
  toe-point paths in their foot's colour (:mod:`humanoid_sim.outputs.colours`);
  ``actual/hip``: the Body-17 CoM path the simulation produced (grey).
- ``ghost/hip``, ``ghost/foot_R``, ``ghost/foot_L``: the reference Body-17 frame (at the reference CoM) and
  the reference Body-1 / Body-2 frames (at the reference toe points) as triads (x red, y green, z blue),
  moving with the reference.
- ``grf/R``, ``grf/L``: the ground reaction force on each foot as an arrow in the foot's colour from its centre of
  pressure, length :data:`FORCE_SCALE` m per N; hidden while the foot is off the ground.
- ``support/<k>``: during phase k, the outline of each sole it stands on (foot colour) and, in double support, the
  support polygon (grey); ``feasibility/cop_R``, ``cop_L``: each foot's centre of pressure (a ball in the foot's
  colour, red when outside its sole); ``feasibility/zmp``: the whole-body ZMP (an orange disc, red when outside the
  support polygon).  These come from the contact audit (:mod:`humanoid_sim.analysis.audit`) and are drawn over the feet.
- ``follow/phase/<k>``: a label above the robot naming the phase on screen (``RFFDSP 2/16``) on a bar of the phase
  colour.  Every phase of the run gets at least one frame (:func:`~.frames.label_track`), even one shorter than a
  frame.

The view follows the robot: the whole scene is moved so that the robot's hip (averaged over half a second) stays
at the point the camera looks at.  Frames are sampled from the log at the display rate (default 30 fps, nearest
logged step); a walk longer than :data:`~.recording.MAX_FRAMES` frames (33 s) is sampled at the lower rate
that keeps that many (:func:`~.recording.playback_fps`), and keys of nodes at rest are dropped
(:func:`~.recording.prune_keys`), so a recording stays under about 5 MB however long the walk (7 s: about 1.3 MB).
Live playback runs a meshcat server bound to
127.0.0.1 only (both its ZeroMQ socket and its web server), so it refuses connections on every other address.
"""

from humanoid_sim.outputs.viewer.frames import (
                                        DISPLAY_FPS,
                                        FORCE_SCALE,
                                        LOOPBACK,
                                        MIN_FORCE,
                                        PlaybackFrames,
                                        ViewerError,
                                        build_frames,
                                        visual_model,
)
from humanoid_sim.outputs.viewer.live import LiveServer, play_live
from humanoid_sim.outputs.viewer.recording import record, write_playback
from humanoid_sim.outputs.viewer.scene import setup_scene

__all__ = ["DISPLAY_FPS", "FORCE_SCALE", "LOOPBACK", "MIN_FORCE", "LiveServer", "PlaybackFrames", "ViewerError",
           "build_frames", "play_live", "record", "setup_scene", "visual_model", "write_playback"]
