"""A trailing foot held flat: the balance controller's departure, on real ground, from the thesis's toe-held double
support.

The thesis's double support holds the trailing foot by its toe body, and its heel rises (toe-off).  A
:class:`FlatTrail` instead gives the QP a weld on the trailing foot's main body (no toe lock, no heel lift), anchored
where it stands at the double support's start, its wrench kept in its heel box cut as its last stance was, and the
posture task holding its toe at its bend:

- in a double support whose trailing foot stood its last stance on a partial foothold (its toe bent on something,
  or its sole cut: :class:`.foothold.Foothold`; ``BalanceSettings.flat_trail``): a toe box bent on an edge, or
  standing half on nothing, cannot carry the foot's load (the toe motor gives 30 N m);
- with ``flat_lead_in``, in the standing lead-in until its toe-off: the whole trailing sole widens the support for a
  CoP that must sit behind the CoM from the first instant (a slope, a push).

Frames: world; units: SI.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin

from humanoid_sim.controllers.balance.foothold import Foothold, FootholdTracker
from humanoid_sim.dynamics.contact import Anchors, ContactSet
from humanoid_sim.robot.phases import FOOT_SPECS, other_foot


class FlatContacts(NamedTuple):
    """One call's contacts with the trailing foot held flat: the contact set, its anchors, the trailing foot's last
    stance (None before any) and the posture's reference angles (26,) with that foot's toe at its bend."""

    contacts: ContactSet
    anchors: Anchors
    held: Foothold | None
    theta0: np.ndarray


class FlatTrail:
    """When and how the trailing foot is held flat (module docstring).

    Args:
        hm: the controller's model (``HumanoidModel``).
        traj: the trajectory (``phases``).
        settings: ``BalanceSettings`` (flat_trail, flat_lead_in, heel_lift_time_s).
        footholds: the foothold tracker (real ground), or None (welds: never held flat).
        theta0: the posture's reference angles (26,).
    """

    def __init__(self, hm: Any, traj: Any, settings: Any, footholds: FootholdTracker | None,
                 theta0: np.ndarray) -> None:
        self.hm, self.model, self.traj, self.s, self.footholds = hm, hm.model, traj, settings, footholds
        self.theta0 = theta0
        self.data = self.model.createData()
        self._main = {f: self.model.getFrameId(spec.main_frame) for f, spec in FOOT_SPECS.items()}
        self._held: tuple[int, pin.SE3, np.ndarray] | None = None   # double support index, anchor, posture angles

    def toe_off(self, k: int) -> float | None:
        """When phase k is the standing lead-in held flat (``flat_lead_in``): the plan's time at which its trailing
        foot's toe-off starts (the lead-in's last ``heel_lift_time_s``), s; else None."""
        s = self.s
        if k != 0 or not (s.flat_lead_in and s.flat_trail and self.footholds is not None):
            return None
        info = self.traj.phases[0]
        return info.t_end - min(info.duration, s.heel_lift_time_s)

    def contacts(self, obs: Any, t: float, kin_data: pin.Data | None) -> FlatContacts | None:
        """The QP's contacts of this call (an ``Observation``; ``t`` the plan's time, s; ``kin_data`` forward
        kinematics at obs.q already computed, or None) with the trailing foot held flat, or None (the phase's own
        contacts: the trailing foot held by its toe)."""
        phase, k = obs.phase, obs.k
        fh = self.footholds
        if fh is None or not phase.is_double_support or obs.anchors is None or not self.s.flat_trail:
            return None
        trail = other_foot(phase.support_foot)
        toe_off = self.toe_off(k)      # the standing lead-in: flat until its toe-off
        lead = toe_off is not None and t < toe_off
        held = fh.stance(trail)
        if not lead and (held is None or held.whole):
            return None
        support, spec = FOOT_SPECS[phase.support_foot], FOOT_SPECS[trail]
        if self._held is None or self._held[0] != k:
            d = kin_data
            if d is None:
                d = self.data
                pin.forwardKinematics(self.model, d, obs.q)
            # the posture task holds that toe at its bend (straightening it would press it into what it stands on)
            i = int(spec.toe_joint[len("theta"):]) - 1
            theta0 = self.theta0.copy()
            theta0[i] = self.hm.theta_from_q(obs.q)[i]
            self._held = (k, pin.SE3(pin.updateFramePlacement(self.model, d, self._main[trail])), theta0)
        contacts = ContactSet(welds=(support.main_frame, spec.main_frame), locks=(support.toe_joint,),
                              name=f"{phase.support_foot}-flat+{trail}-flat")
        anchors = Anchors({**obs.anchors.placements, spec.main_frame: self._held[1]}, obs.anchors.joint_positions)
        return FlatContacts(contacts, anchors, held, self._held[2])
