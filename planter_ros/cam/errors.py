"""The cam's errors: one base class and the cases a caller acts on differently."""

from planter_ros.errors import PlanterError
from planter_ros.kinematics.errors import DesignError

__all__ = ['CamError', 'CamInputError', 'CamLimitError', 'CamPlanningError']


class CamError(PlanterError):
    """Anything the cam planner refuses or fails at; the message is one line."""


class CamInputError(CamError, DesignError):
    """A bad or impossible input (a mechanism, spacing, speed or limit outside its domain): the
    caller fixes the input. A DesignError, so the command line reports it as bad input."""


class CamPlanningError(CamError):
    """The solver failed on an input that should have a plan (a bug to report, not bad input)."""


class CamLimitError(CamInputError):
    """A plan or a run-time transition over the drive's limits that nothing within reach (a
    blend towards constant speed, a transition spread over more plants) brings within them:
    refused before it reaches the drive. The message names the figure and the limit."""
