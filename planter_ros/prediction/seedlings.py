"""Every planting instant accounted for: was a seedling planted, was the cup empty, were there two,
or is it not known, and why.

A planting instant is each time a row's mechanism passes its planting angle (prediction.model).
What it put in the ground comes from the row's seedling sensor, when the machine has one: an
optical cup sensor that counts the seedlings in the cup (or falling through the drop tube) on
its way to the planting point, one reading per cycle (topic `seedlings`,
interfaces.SEEDLINGS: sensor_msgs/JointState, `name` = the row's joint, `position` = the count,
header.stamp = when it was read). Each instant takes the last reading of its row after the
previous instant and not after it:

* status `planted` (1 seedling), `empty` (0), `double` (2 or more): reason `sensed`;
* status `unknown`: reason `no seedling sensor` (the row has none), `no sensor reading` (the
  sensor is there but said nothing this cycle), or `input gap` (no reading, and the instant
  fell in a gap of the ground speed or joint samples).

Whether a row has a sensor is declared in the scene (`seedling_sensor`, `<row>.seedling_sensor`,
rows.RowSettings; recorded in the bag's rows record): a row declared without one has every
instant `unknown`, `no seedling sensor`, and a reading on its joint is not counted; a row
declared with one has `no sensor reading` (or `input gap`) wherever no reading came, also before
its first. Only a row whose declaration is not known (a bag recorded before the setting) is
taken to have a sensor from its first reading on.

An instant inside an input gap (prediction.model: its time and position interpolated, the
model's hole, tilt and upright unknown, flagged `input_gap`) still takes its cycle's reading:
the cup sensor is an input of its own, and a gap in the ground speed or the drive feedback says
nothing about what was in the cup. So an empty cup or a double is counted wherever it falls,
and the tray's losses are counted exactly (a test injects them into simulated runs with gaps).

Spacing (ISO 7256-1, prediction.quality) is measured between the seedlings in the ground: an
empty instant has no spacing and the next seedling's spacing reaches back over it (two spacings
of d become one of 2d: a miss); a double adds a spacing of 0 (a multiple); an unknown instant is
taken as one seedling (without a sensor that is all a machine can say). The plant's `spacing`
field is that spacing (to the previous seedling of its row); a sequence starts again, without a
spacing, after an input gap, a section switched off or a design of another mechanism (as the
model's NaN spacing says). `SeedlingAccount` applies this to plants as they come (the live
monitor) or all at once (replay) with the same arithmetic. Pure numpy.
"""

import math

import numpy as np
from numpy.typing import ArrayLike

from .plants import Plants

__all__ = ['REASONS', 'STATUSES', 'SeedlingAccount', 'design_spacing_of', 'seedling_spacings',
           'status_counts', 'status_name', 'reason_name']

STATUSES = ('planted', 'empty', 'double', 'unknown')
PLANTED, EMPTY, DOUBLE, UNKNOWN = range(4)
REASONS = ('sensed', 'no seedling sensor', 'no sensor reading', 'input gap')
SENSED, NO_SENSOR, NO_READING, INPUT_GAP = range(4)


def status_name(code: float) -> str | None:
    return STATUSES[int(code)] if math.isfinite(code) and 0 <= code < len(STATUSES) else None


def reason_name(code: float) -> str | None:
    return REASONS[int(code)] if math.isfinite(code) and 0 <= code < len(REASONS) else None


class SeedlingAccount:
    """Statuses and seedling spacings of a machine's plants (module doc). Feed the sensor's
    readings with `add_reading` (time order within a row) and the plants with `apply` in time
    order per row. `sensors`: {row index: whether the scene declares a seedling sensor on it
    (None: not declared)}; a row not in it is undeclared. An undeclared row has a sensor from
    its first reading on: an instant before it is `no seedling sensor`, as the live monitor
    sees it."""

    def __init__(self, sensors: dict[int, bool | None] | None = None) -> None:
        self._readings: dict[int, tuple[list[float], list[float]]] = {}   # row -> ([t], [count])
        # row -> (instant time, last seedling position)
        self._last: dict[int, tuple[float, float]] = {}
        self._sensors = {int(row): on for row, on in (sensors or {}).items() if on is not None}

    def add_reading(self, row: int, t: float, count: float) -> None:
        t, count = float(t), float(count)
        if not math.isfinite(t) or self._sensors.get(int(row)) is False:
            return
        times, counts = self._readings.setdefault(int(row), ([], []))
        if times and t <= times[-1]:
            return                         # out of order or repeated: the first is kept
        times.append(t)
        counts.append(count)

    def add_readings(self, row: int, times: ArrayLike, counts: ArrayLike) -> None:
        """Many readings of one row at once, as `add_reading` one by one would keep them."""
        if self._sensors.get(int(row)) is False:
            return                         # the row has no sensor: nothing it reads counts
        t = np.asarray(times, dtype=float)
        count = np.asarray(counts, dtype=float)
        finite = np.isfinite(t)
        t, count = t[finite], count[finite]
        if not t.size:
            return
        held, counts_held = self._readings.setdefault(int(row), ([], []))
        latest = held[-1] if held else -math.inf
        # kept: later than every reading before it (a kept one is the latest so far)
        before = np.maximum.accumulate(np.concatenate(([latest], t[:-1])))
        keep = t > before
        held += t[keep].tolist()
        counts_held += count[keep].tolist()

    def readings(self) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """{row: (times s, counts)} of the readings kept, in time order."""
        return {row: (np.asarray(t, dtype=float), np.asarray(c, dtype=float))
                for row, (t, c) in self._readings.items()}

    def apply(self, plants: Plants, design_spacing: ArrayLike) -> Plants:
        """`plants` (a Plants batch, time order within each row) with seedlings, status,
        reason, spacing and spacing_error set; `design_spacing`: d of each plant (m, array).
        Each row's plants at once, with the arithmetic of one plant after the other."""
        n = len(plants)
        d = np.broadcast_to(np.asarray(design_spacing, dtype=float), (n,))
        seedlings, status = np.full(n, np.nan), np.full(n, float(UNKNOWN))
        reason, spacing = np.full(n, float(NO_SENSOR)), np.full(n, np.nan)
        rows = plants.row.astype(np.int64)
        for row in np.unique(rows).tolist():
            mine = np.flatnonzero(rows == row)
            t, position = plants.time[mine], plants.position[mine]
            gap = plants.input_gap[mine] == 1
            prev_t, last_pos = self._last.get(row, (-math.inf, math.nan))
            # the row's last reading at or before each instant, taken if after the previous
            times, counts = (np.asarray(v, dtype=float) for v in self._readings.get(row, ([],
                                                                                      [])))
            k = np.searchsorted(times, t, side='right') - 1
            read = k >= 0
            at = np.maximum(k, 0)
            count = counts[at] if times.size else np.full(t.size, np.nan)
            with np.errstate(invalid='ignore'):
                sensed = (read & (times[at] > np.concatenate(([prev_t], t[:-1])))
                          if times.size else read)
                sensed &= np.isfinite(count) & (count >= 0)
                code = np.where(count < 0.5, EMPTY, np.where(count >= 1.5, DOUBLE, PLANTED))
            declared = self._sensors.get(row)
            if declared is False:                    # no seedling sensor, declared
                reason[mine] = np.where(sensed, SENSED, NO_SENSOR)
            else:                                    # a declared one misses its reading
                reason[mine] = np.where(sensed, SENSED, np.where(
                    gap, INPUT_GAP, np.where(read | bool(declared), NO_READING, NO_SENSOR)))
            seedlings[mine] = np.where(sensed, count, np.nan)
            status[mine] = np.where(sensed, code, UNKNOWN)
            # the last seedling's position before each instant: none where the model's
            # sequence starts again (there), an empty instant keeps the one before it
            empty = sensed & (code == EMPTY)
            restart = ~np.isfinite(plants.spacing[mine]) | gap
            order = np.arange(t.size)
            seedling = np.maximum.accumulate(np.where(empty, -1, order))    # last non-empty
            cut = np.maximum.accumulate(np.where(restart, order, -2))       # last restart
            after = np.where(seedling >= 0,              # ... and after each instant
                             np.where(seedling >= cut, position[np.maximum(seedling, 0)],
                                      np.nan),
                             np.where(cut == -2, last_pos, np.nan))
            before = np.where(restart, np.nan, np.concatenate(([last_pos], after[:-1])))
            spacing[mine] = np.where(empty, np.nan, position - before)
            self._last[row] = (float(t[-1]), float(after[-1]))
        values = {f: getattr(plants, f) for f in plants.__dataclass_fields__}
        values.update(seedlings=seedlings, status=status, reason=reason, spacing=spacing,
                      spacing_error=spacing - d)
        return Plants(**values)


def design_spacing_of(plants: Plants, fallback: float) -> np.ndarray:
    """d of each plant: spacing − spacing_error where both are known, else `fallback`."""
    d = plants.spacing - plants.spacing_error
    return np.where(np.isfinite(d), d, float(fallback))


def seedling_spacings(plants: Plants,
                      design_spacing: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """(spacings, their d) between the seedlings in the ground: each plant's spacing, and a
    spacing of 0 for each seedling past the first of a double (module doc)."""
    d = np.broadcast_to(np.asarray(design_spacing, dtype=float), plants.spacing.shape)
    extra = np.where(plants.status == DOUBLE,
                     np.maximum(np.nan_to_num(plants.seedlings, nan=2.0) - 1.0, 1.0), 0.0)
    extra = extra.astype(int)
    x = np.concatenate((plants.spacing, np.zeros(int(extra.sum()))))
    x_d = np.concatenate((d, np.repeat(d, extra)))
    return x, x_d


def status_counts(plants: Plants) -> dict[str, int]:
    """{status: instants} and {'input_gap': instants in a gap} of a set of plants."""
    out = {name: int(np.count_nonzero(plants.status == code))
           for code, name in enumerate(STATUSES)}
    out['input_gap'] = int(np.count_nonzero(plants.input_gap == 1))
    out['seedlings'] = int(np.nansum(np.where(plants.status == UNKNOWN, 1.0,
                                              plants.seedlings)))
    return out
