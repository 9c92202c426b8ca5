"""Piecewise polynomials of degree ≤ 5 with a scalar evaluation cheap enough for a control loop.

A cam is stored as breakpoints and, per piece, the six coefficients of θ(r) = Σ c_j (r − r_i)^j.
`Piecewise.at` finds the piece with `bisect` and evaluates θ, θ′ and θ″ by Horner's rule in plain
Python floats (about a µs; no numpy, no scipy per call); `values` does arrays through scipy's
PPoly of the same coefficients (`to_scipy`), an independent evaluation of the same function.
"""

from bisect import bisect_right
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from planter_ros.kinematics.arrays import FloatArray

if TYPE_CHECKING:
    from scipy.interpolate import PPoly

__all__ = ['Piecewise', 'DEGREE', 'State']

DEGREE = 5
# (θ, θ′, θ″) of a cam at one distance: rad, rad/m, rad/m²
State = tuple[float, float, float]


class Piecewise:
    """θ(r) on [breaks[0], breaks[-1]]; outside it the end pieces are extended."""

    __slots__ = ('breaks', 'coeffs', '_breaks', '_rows', '_inner', '_ppoly')

    def __init__(self, breaks: ArrayLike, coeffs: ArrayLike) -> None:
        breaks = np.asarray(breaks, dtype=np.float64)
        coeffs = np.asarray(coeffs, dtype=np.float64)
        if coeffs.ndim != 2 or coeffs.shape[1] > DEGREE + 1:
            raise ValueError(f'coefficients of shape {coeffs.shape}: need (pieces, <= 6)')
        coeffs = np.pad(coeffs, ((0, 0), (0, DEGREE + 1 - coeffs.shape[1])))
        if breaks.ndim != 1 or breaks.size != coeffs.shape[0] + 1 or \
                not np.all(np.diff(breaks) > 0):
            raise ValueError('breaks must increase and number one more than the pieces')
        if not (np.all(np.isfinite(breaks)) and np.all(np.isfinite(coeffs))):
            raise ValueError('non-finite breaks or coefficients')
        self.breaks: FloatArray = breaks
        self.coeffs: FloatArray = coeffs
        self._breaks: list[float] = breaks.tolist()
        self._rows: list[tuple[float, ...]] = [tuple(row) for row in coeffs.tolist()]
        self._inner = self._breaks[1:-1]
        self._ppoly: PPoly[np.float64] | None = None

    @property
    def start(self) -> float:
        return self._breaks[0]

    @property
    def end(self) -> float:
        return self._breaks[-1]

    def at(self, r: float) -> State:
        """(θ, θ′, θ″) at a scalar r (float arithmetic only)."""
        i = bisect_right(self._inner, r)
        c0, c1, c2, c3, c4, c5 = self._rows[i]
        x = r - self._breaks[i]
        return (c0 + x * (c1 + x * (c2 + x * (c3 + x * (c4 + x * c5)))),
                c1 + x * (2.0 * c2 + x * (3.0 * c3 + x * (4.0 * c4 + x * 5.0 * c5))),
                2.0 * c2 + x * (6.0 * c3 + x * (12.0 * c4 + x * 20.0 * c5)))

    def values(self, r: ArrayLike, order: int = 0) -> FloatArray:
        """The `order`-th derivative (0..3) at an array of r, through scipy's PPoly of the
        same coefficients: arithmetic independent of `at`'s, so each checks the other."""
        if self._ppoly is None:
            self._ppoly = self.to_scipy()
        return self._ppoly(np.asarray(r, dtype=np.float64), order)

    def to_scipy(self) -> 'PPoly[np.float64]':
        """The same function as scipy.interpolate.PPoly (highest power first)."""
        # lazy: scipy.interpolate costs 0.39 s (python -X importtime) and the control loop,
        # which evaluates planned cams by `at`, never needs it
        from scipy.interpolate import PPoly
        return PPoly(self.coeffs[:, ::-1].T.copy(), self.breaks.copy())

    def shifted(self, offset: float) -> 'Piecewise':
        """The same polynomials with every break moved by `offset`."""
        return Piecewise(self.breaks + offset, self.coeffs)

    @staticmethod
    def join(parts: Sequence['Piecewise']) -> 'Piecewise':
        """Consecutive pieces (each part starting where the previous ended) as one."""
        breaks = [parts[0].breaks]
        for prev, part in zip(parts, parts[1:]):
            if part.breaks[0] != prev.breaks[-1]:
                raise ValueError(f'parts do not meet: {prev.breaks[-1]!r} != {part.breaks[0]!r}')
            breaks.append(part.breaks[1:])
        return Piecewise(np.concatenate(breaks), np.concatenate([p.coeffs for p in parts]))
