"""Bring your own controller: the API (Observation, Param, Controller), loading by spec, the guard.

    from hopper.controllers import Observation, Param

See README.md ("Bring your own controller") and examples/my_controller.py.
"""

from hopper.controllers.api import Controller, ControllerContext, ControllerError, Observation, Param
from hopper.controllers.law import BUDGET_US, ControllerFault, FlightLaw, params_of, with_controller
from hopper.controllers.loading import BUILTIN, ENTRY_POINT_GROUP, build, load_class

__all__ = [
    "BUDGET_US",
    "BUILTIN",
    "ENTRY_POINT_GROUP",
    "Controller",
    "ControllerContext",
    "ControllerError",
    "ControllerFault",
    "FlightLaw",
    "Observation",
    "Param",
    "build",
    "load_class",
    "params_of",
    "with_controller",
]
