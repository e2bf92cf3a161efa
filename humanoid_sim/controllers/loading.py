"""A user's controller by dotted name (``package.module:ClassName``), as a scenario's ``controller_class`` gives it."""

from __future__ import annotations

import importlib

from humanoid_sim.errors import InputError
from humanoid_sim.interfaces.controller import Controller
from humanoid_sim.scenario.schema import DOTTED_CLASS


class ControllerLoadError(InputError):
    """The named controller cannot be loaded or is not a controller (bad input: the message names the value)."""


def load_controller(spec: str, field: str = "controller_class") -> Controller:
    """Import ``module:Class`` and return ``Class()``; it must have ``setup(ctx)`` and be callable
    (:class:`humanoid_sim.interfaces.controller.Controller`)."""
    if not isinstance(spec, str) or not DOTTED_CLASS.match(spec):
        raise ControllerLoadError(f"{field}: expected 'package.module:ClassName', got {spec!r}")
    module_name, cls_name = spec.split(":")
    try:
        module = importlib.import_module(module_name)
    except Exception as exc:  # ImportError, or the module failed while importing
        raise ControllerLoadError(f"{field}: cannot import module {module_name!r} ({type(exc).__name__}: {exc}); "
                                  "is its folder on PYTHONPATH?") from exc
    cls = getattr(module, cls_name, None)
    if cls is None:
        raise ControllerLoadError(f"{field}: module {module_name!r} has no {cls_name!r}")
    try:
        obj = cls()
    except Exception as exc:
        raise ControllerLoadError(f"{field}: {spec}() failed ({type(exc).__name__}: {exc}); a controller class is "
                                  "constructed without arguments") from exc
    if not (callable(obj) and callable(getattr(obj, "setup", None))):
        raise ControllerLoadError(f"{field}: {spec} is not a controller: it needs a setup(ctx) method and a "
                                  "__call__(obs) method (humanoid_sim.interfaces.controller.Controller)")
    if not isinstance(getattr(obj, "name", None), str):
        obj.name = spec
    return obj
