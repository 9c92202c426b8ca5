"""Injected losses against what the analysis counts: the tray's empty cells and doubles, and the
instants inside input gaps, accounted for one by one (the check of a simulated season).

What is injected is what each row's cup sensor read (`planter simulate`'s tray: one reading per
cycle, 0 = an empty cell, 2 = a double). What is counted is the status of each planting instant
(prediction.seedlings). Every reading ends up in exactly one place:

* taken by a planting instant: that instant is `empty`, `planted` or `double` by it, whether it
  fell inside an input gap or not (an instant in a gap keeps its reading: prediction.seedlings);
* read before the first planting instant the recording places (the cup passed the sensor, but
  the planting instant came before the first ground-speed sample: it has no position, so it is
  not an instant of the bag; the first placed instant takes its own, later reading);
* read after the last planting instant (the recording ended between the cup sensor and the
  planting point);
* superseded: a second reading in one cycle (a sensor that reads twice; the later one counts).

So `injected == counted + before the first + after the last + superseded`, kind by kind, with
no tolerance. The ISO 7256-1 indices (prediction.quality) count spacings, not cells: a run of
empty cells between two seedlings of one measured sequence is one miss, an empty cell with no
spacing across it (inside or next to an input gap, at the start or the end of a row's
sequence) is counted as an empty instant but is no miss; each seedling past the first of a
double is one multiple. Misses and multiples the spacings show without an empty cell or a
double (a drive stall's phase slip) are the kinematic ones, listed apart. Pure numpy.
"""

from dataclasses import dataclass

import numpy as np

from planter_ros.prediction.seedlings import DOUBLE, EMPTY, PLANTED, UNKNOWN

KINDS = ('empty', 'single', 'double')
_KIND = {0: 'empty', 1: 'single', 2: 'double'}


def _kind(count):
    return 'empty' if count < 0.5 else 'double' if count >= 1.5 else 'single'


# the plants table's columns an accounting reads, in Instants' order
INSTANT_COLUMNS = ('row', 'time', 'status', 'seedlings', 'input_gap', 'spacing',
                   'spacing_error')


@dataclass(frozen=True)
class Instants:
    """The planting instants of one bag, column by column (arrays of one length: the plants
    table's INSTANT_COLUMNS or replay's plants): each instant's row, time (s), status code,
    seedlings, input_gap flag, spacing and spacing error (m)."""

    row: np.ndarray
    time: np.ndarray
    status: np.ndarray
    seedlings: np.ndarray
    input_gap: np.ndarray
    spacing: np.ndarray
    spacing_error: np.ndarray

    @classmethod
    def of(cls, *columns):
        """Instants of the columns in INSTANT_COLUMNS' order, as float arrays."""
        return cls(*(np.asarray(a, dtype=float) for a in columns))


def account(readings, instants):
    """The accounting of one bag (module doc): `readings` {row index: (times s, counts)} the cup
    sensors read (replay's `seedling_readings`), then its planting `instants` (Instants).
    Returns a dict of counts (see `add`); `mismatched` counts sensed instants whose count is
    not their cycle's reading (0 when the pipeline is right)."""
    out = empty_account()
    row = instants.row
    for r in np.unique(row[np.isfinite(row)]).tolist() + [
            r for r in readings if not np.any(row == r)]:
        mine = np.flatnonzero(row == r)
        mine = mine[np.argsort(instants.time[mine], kind='stable')]
        _row(out, readings.get(int(r), (np.zeros(0), np.zeros(0))), mine, instants)
    return out


def empty_account():
    return {'injected': dict.fromkeys(KINDS, 0), 'counted': dict.fromkeys(KINDS, 0),
            'unknown': 0, 'instants': 0, 'in_gap': dict.fromkeys(KINDS, 0), 'gap_unknown': 0,
            'before_first': dict.fromkeys(KINDS, 0), 'after_last': dict.fromkeys(KINDS, 0),
            'superseded': dict.fromkeys(KINDS, 0), 'mismatched': 0,
            'misses_of_empties': 0, 'empties_without_spacing': 0, 'misses_kinematic': 0,
            'multiples_of_doubles': 0, 'multiples_kinematic': 0}


def add(total, one):
    """Sum two accountings (dicts of counts, nested one level)."""
    for key, value in one.items():
        if isinstance(value, dict):
            for kind, n in value.items():
                total[key][kind] += n
        else:
            total[key] += value
    return total


def is_exact(acc):
    """Every injected cell accounted for, kind by kind, and every sensed count its reading."""
    return acc['mismatched'] == 0 and all(
        acc['injected'][k] == acc['counted'][k] + acc['before_first'][k]
        + acc['after_last'][k] + acc['superseded'][k] for k in KINDS)


def _row(out, reading, mine, instants):
    """Add the accounting of one row to `out`: its cup sensor's `reading` (times s, counts) and
    its planting instants `instants` at the positions `mine` (in time order)."""
    time, status, seedlings = instants.time, instants.status, instants.seedlings
    input_gap, spacing, spacing_error = (instants.input_gap, instants.spacing,
                                         instants.spacing_error)
    r_t, r_c = (np.asarray(a, dtype=float) for a in reading)
    for c in r_c.tolist():
        out['injected'][_kind(c)] += 1
    t = time[mine]
    out['instants'] += mine.size
    # which reading each instant took: the last one after the previous instant, not after it
    k = np.searchsorted(r_t, t, side='right') - 1
    previous = np.concatenate(([-np.inf], t[:-1]))
    took = (k >= 0) & (r_t[np.maximum(k, 0)] > previous) if r_t.size else \
        np.zeros(t.size, dtype=bool)
    taken = np.zeros(r_t.size, dtype=bool)
    taken[k[took]] = True
    for p, q in zip(np.flatnonzero(took).tolist(), k[took].tolist()):
        if seedlings[mine[p]] != r_c[q]:
            out['mismatched'] += 1
    codes = {PLANTED: 'single', EMPTY: 'empty', DOUBLE: 'double'}
    st = status[mine]
    gap = input_gap[mine] == 1
    for code, kind in codes.items():
        out['counted'][kind] += int(np.count_nonzero(st == code))
        out['in_gap'][kind] += int(np.count_nonzero((st == code) & gap))
    out['unknown'] += int(np.count_nonzero(st == UNKNOWN))
    out['gap_unknown'] += int(np.count_nonzero((st == UNKNOWN) & gap))
    # readings no instant took: before the first instant, after the last, or superseded
    first, last = (t[0], t[-1]) if t.size else (np.inf, -np.inf)
    for q in np.flatnonzero(~taken).tolist():
        where = ('after_last' if r_t[q] > last else 'before_first' if r_t[q] <= first
                 else 'superseded')
        out[where][_kind(r_c[q])] += 1
    # the ISO counts from the spacings between the seedlings in the ground
    x = spacing[mine]
    d = x - spacing_error[mine]
    after_empty = np.concatenate(([False], st[:-1] == EMPTY))
    measured = np.isfinite(x)
    miss = measured & (x > 1.5 * d)
    out['misses_kinematic'] += int(np.count_nonzero(miss & ~after_empty))
    # a run of empties: counted once, at the seedling whose spacing reaches back over it
    runs = (st == EMPTY) & ~np.concatenate(([False], st[:-1] == EMPTY))
    run_end = np.flatnonzero(runs)
    for start in run_end.tolist():
        stop = start
        while stop < st.size and st[stop] == EMPTY:
            stop += 1
        if stop < st.size and measured[stop] and x[stop] > 1.5 * d[stop]:
            out['misses_of_empties'] += 1
        else:
            out['empties_without_spacing'] += stop - start
    doubles = st == DOUBLE
    extra = np.maximum(np.nan_to_num(seedlings[mine], nan=2.0) - 1.0, 1.0)
    out['multiples_of_doubles'] += int(np.sum(np.where(doubles, extra, 0.0)))
    out['multiples_kinematic'] += int(np.count_nonzero(measured & (x <= 0.5 * d)))


def lines(acc, bags=None, misses=None, multiples=None):
    """The accounting for people: injected against counted, each difference by its place."""
    def kinds(counts):
        return f"{counts['empty']} empty, {counts['single']} single, {counts['double']} double"
    head = f'{bags} bags: ' if bags is not None else ''
    out = [f"{head}cells read by the cup sensors: {sum(acc['injected'].values())} "
           f"({kinds(acc['injected'])}); planting instants: {acc['instants']} "
           f"({acc['counted']['empty']} empty, {acc['counted']['single']} planted, "
           f"{acc['counted']['double']} double, {acc['unknown']} unknown)",
           f"  inside input gaps (position interpolated, reading kept): "
           f"{sum(acc['in_gap'].values())} instants ({kinds(acc['in_gap'])}), "
           f"{acc['gap_unknown']} unknown (no reading)",
           f"  read before the first placed instant (planted before the first ground-speed "
           f"sample): {kinds(acc['before_first'])}",
           f"  read after the last instant (the recording ended between the cup sensor and the "
           f"planting point): {kinds(acc['after_last'])}",
           f"  superseded (two readings in one cycle): {kinds(acc['superseded'])}",
           f"  injected = counted + read before the first + after the last + superseded: "
           f"{'exact' if is_exact(acc) else 'NOT exact'} (empty {acc['injected']['empty']} = "
           f"{acc['counted']['empty']} + {acc['before_first']['empty']} + "
           f"{acc['after_last']['empty']} + {acc['superseded']['empty']}; double "
           f"{acc['injected']['double']} = {acc['counted']['double']} + "
           f"{acc['before_first']['double']} + {acc['after_last']['double']} + "
           f"{acc['superseded']['double']}); sensed counts not their reading: "
           f"{acc['mismatched']}"]
    iso = (f"  ISO 7256-1: misses {misses} = {acc['misses_of_empties']} runs of empty cells "
           f"+ {acc['misses_kinematic']} kinematic; multiples {multiples} = "
           f"{acc['multiples_of_doubles']} of doubles + {acc['multiples_kinematic']} "
           f"kinematic; {acc['empties_without_spacing']} empty cells without a spacing across "
           f"them (next to a gap, at a row's start or end): empty instants, no miss")
    out.append(iso)
    return out
