"""Spacing quality as agronomists and machine testers measure it (ISO 7256-1; Kachman and Smith,
"Alternative measures of accuracy in plant spacing for planters using single seed metering",
Transactions of the ASAE 38(2):379-387, 1995).

From the spacings x of consecutive plants of one row against the design spacing d:

* multiple index   = share of x <= 0.5 d (two plants where one belongs);
* miss index       = share of x > 1.5 d (a plant missing);
* quality of feed  = 1 - multiple index - miss index (the share of single spacings);
* precision        = coefficient of variation (sample standard deviation over mean) of the
  single spacings, x in (0.5 d, 1.5 d]. Kachman and Smith divide that standard deviation by d
  instead of the singles' mean; the two agree when the singles average d.

All fractions 0..1. A spacing that is NaN does not count: the first plant of a row and the first
plant after an input gap or a section switched off have none. With several design spacings in one
run (a design change), each spacing is judged against its own d (the ratio x/d is what counts).
Undefined values are None: every index without spacings, the precision with fewer than two single
spacings.

`SpacingQuality` keeps running counts (the live monitor adds each plant's spacing as it comes);
`spacing_quality` and `spacing_quality_by_row` judge a whole run at once (replay) through the
same class. Pure numpy: no ROS.
"""

from collections.abc import Iterable, Mapping
import math

import numpy as np
from numpy.typing import ArrayLike

__all__ = ['QUALITY_FIELDS', 'MULTIPLE_LIMIT', 'MISS_LIMIT', 'QualityIndices', 'SpacingQuality',
           'spacing_quality', 'spacing_quality_by_row', 'format_quality']

# the indices in the order the monitor's topic and the JSON give them ('spacings': the count)
QUALITY_FIELDS = ('multiple_index', 'miss_index', 'quality_of_feed_index', 'precision',
                  'spacings')
MULTIPLE_LIMIT = 0.5           # x <= 0.5 d: a multiple
MISS_LIMIT = 1.5               # x > 1.5 d: a miss


# the indices by name (quality_of_feed_index, multiple_index, miss_index, precision: fractions or
# None without spacings; spacings: their count), JSON-ready
QualityIndices = dict[str, float | int | None]


class SpacingQuality:
    """Running spacing-quality counts of one row (or of the whole machine)."""

    def __init__(self) -> None:
        self.spacings = 0          # spacings counted
        self.multiples = 0
        self.misses = 0
        self._singles = 0          # spacings in (0.5 d, 1.5 d], their x/d:
        self._mean = 0.0           # running mean and
        self._m2 = 0.0             # sum of squared deviations (Chan et al.'s pairwise update)

    def add(self, spacing: ArrayLike, design_spacing: ArrayLike) -> 'SpacingQuality':
        """Count the spacings (m; NaN ones are skipped) against the design spacing d (m, a
        number or one per spacing). Returns self."""
        x = np.atleast_1d(np.asarray(spacing, dtype=float))
        d = np.broadcast_to(np.asarray(design_spacing, dtype=float), x.shape)
        ok = np.isfinite(x) & np.isfinite(d) & (d > 0)
        ratio = x[ok] / d[ok]
        if not ratio.size:
            return self
        multiple = ratio <= MULTIPLE_LIMIT
        miss = ratio > MISS_LIMIT
        singles = ratio[~(multiple | miss)]
        self.spacings += int(ratio.size)
        self.multiples += int(np.count_nonzero(multiple))
        self.misses += int(np.count_nonzero(miss))
        if singles.size:
            n_b = int(singles.size)
            mean_b = float(singles.mean())
            m2_b = float(np.sum((singles - mean_b) ** 2))
            n = self._singles + n_b
            delta = mean_b - self._mean
            self._mean += delta * n_b / n
            self._m2 += m2_b + delta * delta * self._singles * n_b / n
            self._singles = n
        return self

    def result(self) -> QualityIndices:
        """{multiple_index, miss_index, quality_of_feed_index, precision, spacings}: fractions
        0..1 or None when undefined, and the count of spacings used."""
        n = self.spacings
        if not n:
            return {'multiple_index': None, 'miss_index': None, 'quality_of_feed_index': None,
                    'precision': None, 'spacings': 0}
        multiple, miss = self.multiples / n, self.misses / n
        precision = None
        if self._singles >= 2 and self._mean > 0:
            precision = math.sqrt(max(self._m2, 0.0) / (self._singles - 1)) / self._mean
        return {'multiple_index': multiple, 'miss_index': miss,
                'quality_of_feed_index': (n - self.multiples - self.misses) / n,
                'precision': precision, 'spacings': n}


def spacing_quality(spacing: ArrayLike, design_spacing: ArrayLike) -> QualityIndices:
    """The indices of one set of spacings (see the module doc)."""
    return SpacingQuality().add(spacing, design_spacing).result()


def spacing_quality_by_row(spacing: ArrayLike, design_spacing: ArrayLike, row: ArrayLike,
                           rows: Iterable[int] | None = None
                           ) -> tuple[dict[int, QualityIndices], QualityIndices]:
    """(indices of each row {row index: result}, indices of the whole machine): every row's
    spacings judged alike, the machine's = all rows' spacings together. `rows`: the row indices
    to report (those without plants get an empty result); default: the rows present."""
    spacing = np.asarray(spacing, dtype=float)
    row = np.asarray(row, dtype=float)
    design_spacing = np.broadcast_to(np.asarray(design_spacing, dtype=float), spacing.shape)
    indices = sorted(set(int(r) for r in np.unique(row))) if rows is None else list(rows)
    per_row = {int(r): spacing_quality(spacing[row == r], design_spacing[row == r])
               for r in indices}
    return per_row, spacing_quality(spacing, design_spacing)


def format_quality(quality: Mapping[str, float | int | None]) -> str:
    """One line for people: percentages with what each index counts."""
    def pct(value: float | None) -> str:
        return 'n/a' if value is None else f'{100 * value:.1f} %'
    return (f"quality of feed {pct(quality['quality_of_feed_index'])}, multiples "
            f"{pct(quality['multiple_index'])} (x <= 0.5 d), misses {pct(quality['miss_index'])}"
            f" (x > 1.5 d), precision {pct(quality['precision'])} (CV of x in (0.5 d, 1.5 d]); "
            f"{quality['spacings']} spacings")
