"""The constraint model of welded feet, as an engine offers it to controllers (``ControlContext.constraints``)."""

from __future__ import annotations

from humanoid_sim.dynamics.contact import ContactDynamics


class WeldModel:
    """The phase's welds and toe locks as Pinocchio KKT rows.

    Attributes:
        kind: ``"weld"``.
        dyn: the contact dynamics (:class:`humanoid_sim.dynamics.contact.ContactDynamics`) that gives the rows.
    """

    kind = "weld"

    def __init__(self, dyn: ContactDynamics) -> None:
        self.dyn = dyn


__all__ = ["WeldModel"]
