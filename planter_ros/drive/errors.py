"""The drive's exception family: one base, one subclass per way a drive operation fails, so a
caller reacts to the kind of failure, never to the wording. Every message is one line."""

from planter_ros.config import ConfigError
from planter_ros.errors import PlanterError


class DriveError(PlanterError, RuntimeError):
    """A drive operation failed (base of the family)."""


class DriveConfigError(DriveError, ConfigError):
    """A drive setting out of range (before anything touches the bus)."""


class NotConnectedError(DriveError):
    """A command before connect_and_enable() succeeded, or after shutdown()."""


class BusError(DriveError):
    """The CAN bus could not be opened, or a frame could not be sent."""


class DriveTimeoutError(DriveError):
    """The drive did not answer (SDO) or did not reach a state in time."""


class DriveRefusedError(DriveError):
    """The drive answered no: an SDO abort, or it is not the drive the configuration says
    (device type, operation modes, encoder resolution)."""


class DictionaryError(DriveConfigError):
    """The drive's EDS/DCF cannot be read, or lacks what the row's mode needs: one line naming
    the object, what it is for and what to do (before anything moves)."""
