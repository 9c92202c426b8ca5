"""The one error type of the core: a bad or infeasible input, said in one line."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from planter_ros.config import ConfigError


class DesignError(ConfigError):
    """An input outside the domain where the design exists.

    The message is one line naming the value and its allowed range, so a command line can print
    it as is and a node can refuse a parameter update with it.
    """

    def __init__(self, parameter: str, value: object, allowed: str, reason: str = '') -> None:
        # None on an error made from a ready message (from_message)
        self.parameter: str | None = parameter
        self.value: object = value
        self.allowed: str | None = allowed
        text = f'{parameter} = {value:.6g}' if isinstance(value, (int, float)) else \
            f'{parameter} = {value}'
        text += f' is out of range: allowed {allowed}'
        if reason:
            text += f' ({reason})'
        super().__init__(text, where=parameter, limit=allowed)

    @classmethod
    def from_message(cls, text: str) -> DesignError:
        """A DesignError with a ready one-line message (a config range check's)."""
        err = cls.__new__(cls)
        ConfigError.__init__(err, text)
        err.parameter = err.value = err.allowed = None
        return err


def require_positive_finite(name: str, value: npt.ArrayLike, unit: str = '') -> None:
    """Raise DesignError unless value is a finite number > 0 (scalars and arrays alike)."""
    if isinstance(value, (int, float)):
        if not (math.isfinite(value) and value > 0):
            raise DesignError(name, value, f'finite and > 0{(" " + unit) if unit else ""}')
        return
    arr = np.asarray(value, dtype=float)
    bad = ~(np.isfinite(arr) & (arr > 0))
    if np.any(bad):
        first = float(arr[bad].flat[0]) if arr.ndim else float(arr)
        raise DesignError(name, first, f'finite and > 0{(" " + unit) if unit else ""}')
