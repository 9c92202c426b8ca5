"""One row's cam over its own travelled distance, with run-time spacing changes.

A `CamTrack` starts with one profile (plant 0 at s = `origin`, θ = π + 2π·`turn`). `change`
hands it a new profile (another spacing, another rule): the change takes effect at the next
planting instant s_k after the distance `s_now` at which it is asked — the plant at s_k is the
old spacing's last, the next plant is the new spacing d′ further on, at s_k + d′ — with no jump
in θ, θ′ or θ″:

* the old profile runs on to its soil exit after s_k;
* an out-of-soil transition arc (`arc.plan_arc`, the new profile's speed and limits) joins the
  old exit's state to the new profile's soil entry before s_k + d′, C2 at both ends;
* from that entry the new profile runs, its plants at s_k + j·d′, θ = π + 2π(k + j).

If both profiles have the same in-soil law (the same rule at another spacing: the exact
zero-slip and the design-speed rules do not depend on the spacing) the new profile's own
out-of-soil arc is that transition, and nothing is planned at run time.

Every planned transition is checked against the drive's limits at the new profile's planning
(top) speed (`plan_transition`): its peaks, and the RMS torque over the drive's thermal
window (the rated torque is a thermal limit: the transition's heat and, for the rest of the
window, the hotter steady profile's). One over
a limit is spread over more plants: plants 1..k−1 after s_k get gaps stepping from the old
spacing to the new and in-soil laws stepping from the old law to the new (blends), each joined
to the next by its own arc, and the new profile runs from plant k; k grows up to
`MAX_TRANSITION_PLANTS`. A change nothing
brings within the limits is refused (`CamLimitError`, naming the figure and the limit) and the
track is left as it was. A transition depends only on the two profiles (it is planned relative
to s_k), so it is planned once and cached under the two profiles' fingerprints: a caller can
plan it off the control thread (`plan_transition`) or hand in one planned elsewhere
(`remember_transition`).

`evaluate(s)` is the per-cycle call: a bisect over the few segments, then the profile's own
evaluation. Pure Python floats; no ROS.
"""

from bisect import bisect_left, bisect_right
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
import hashlib
import math
import threading
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from planter_ros.kinematics.arrays import FloatArray
from planter_ros.kinematics.five_bar import TWO_PI

from .arc import ARC_PIECES, ArcEnds, plan_arc
from .drive import LoadFigures, LoadSamples, TorqueTerms, sun_bar_motion
from .errors import CamInputError, CamLimitError
from .piecewise import Piecewise, State
from .plan import CamProfile, soil_arc

__all__ = ['CamTrack', 'MAX_TRANSITION_PLANTS', 'Transition', 'fingerprint', 'plan_transition',
           'remember_transition']

MAX_TRANSITION_PLANTS = 6        # a transition is spread over at most this many plants
_CACHE_SIZE = 32


def fingerprint(profile: CamProfile) -> str:
    """A profile's identity by content (its mechanism, law, spacing, speed, drive and
    coefficients): the same in the process that planned it and in one that rebuilt it from
    `control.cam_law.profile_to_data` (floats survive JSON exactly)."""
    if profile._fingerprint is not None:
        return profile._fingerprint
    digest = hashlib.sha256()
    digest.update(repr((profile.mech, profile.law.zero_slip, profile.law.advance,
                        profile.spacing, profile.speed, profile.drive)).encode())
    digest.update(profile.period.breaks.tobytes())
    digest.update(profile.period.coeffs.tobytes())
    known = profile._fingerprint = digest.hexdigest()[:32]
    return known


@dataclass(frozen=True)
class Transition:
    """A change from profile `old` to profile `new`, relative to the old spacing's last plant
    (r = s − s_k = 0, θ − 2π·turn = π). `gaps`: the distances from each plant of the change to
    the next, k of them (the last is the new spacing d′): plant m at r = gaps[0] + … +
    gaps[m−1] with θ = π + 2πm, the new profile's own plants from plant k on; `piecewise`
    θ(r) from the old soil exit to plant k's soil entry (None when both profiles have the same
    in-soil law: no arc, k = 1); `figures` its loads at `speed` (None without an arc)."""

    old: str                         # fingerprints
    new: str
    gaps: tuple[float, ...]
    piecewise: Piecewise | None
    figures: LoadFigures | None
    speed: float

    @property
    def plants(self) -> int:
        return len(self.gaps)

    def as_data(self) -> dict[str, Any]:
        """JSON-ready data (`from_data` reads it back exactly)."""
        pw = self.piecewise
        return {'old': self.old, 'new': self.new, 'gaps': list(self.gaps), 'speed': self.speed,
                'breaks': None if pw is None else pw.breaks.tolist(),
                'coeffs': None if pw is None else pw.coeffs.tolist()}

    @classmethod
    def from_data(cls, data: Mapping[str, Any]) -> 'Transition':
        pw = None if data['breaks'] is None else Piecewise(data['breaks'], data['coeffs'])
        gaps = tuple(float(g) for g in data['gaps'])
        if not gaps or not all(math.isfinite(g) and g > 0 for g in gaps):
            raise ValueError(f'transition gaps {data["gaps"]!r}: allowed positive distances')
        return cls(str(data['old']), str(data['new']), gaps, pw, None, float(data['speed']))


_cache: OrderedDict[tuple[str, str], Transition] = OrderedDict()
_cache_lock = threading.Lock()


def remember_transition(transition: Transition) -> None:
    """Keep a transition planned elsewhere (a shell planning for its command process) so a
    `CamTrack.change` between the same two profiles uses it instead of planning."""
    with _cache_lock:
        _cache[(transition.old, transition.new)] = transition
        _cache.move_to_end((transition.old, transition.new))
        while len(_cache) > _CACHE_SIZE:
            _cache.popitem(last=False)


def _known(old: CamProfile, new: CamProfile) -> Transition | None:
    with _cache_lock:
        return _cache.get((fingerprint(old), fingerprint(new)))


def _placed(parts: Sequence[tuple[Piecewise, float, float]]) -> Piecewise:
    """One Piecewise of consecutive parts (piecewise, r of its first break, θ added): each
    part's local polynomials kept, its breaks moved; where two parts meet the first break of
    the later one is taken as the earlier one's end."""
    breaks: list[FloatArray] = []
    coeffs: list[FloatArray] = []
    end = 0.0
    for pw, r0, dtheta in parts:
        b = pw.breaks - pw.breaks[0] + r0
        c = pw.coeffs.copy()
        c[:, 0] += dtheta
        breaks.append(b[:-1])
        coeffs.append(c)
        end = float(b[-1])
    return Piecewise(np.concatenate(breaks + [[end]]), np.concatenate(coeffs))


def _spread(old: CamProfile, new: CamProfile, plants: int) -> tuple[
        tuple[float, ...], Piecewise, Piecewise, list[tuple[float, float]]]:
    """The transition over `plants` = k plants (module doc): (gaps, the piecewise from the old
    exit to plant k's entry, the stretch judged and its RMS window). Plant m (1 ≤ m < k) sits
    a gap stepped from the old spacing towards the new after the one before and has an
    in-soil law stepped from the old law towards the new (blends)."""
    mech, d, d_old = new.mech, new.spacing, old.spacing
    gaps = tuple(d_old + (d - d_old) * m / plants for m in range(1, plants + 1))
    at = [0.0]
    for gap in gaps:
        at.append(at[-1] + gap)
    laws = [old.law] + [old.law.blend(new.law, 1.0 - m / plants) for m in range(1, plants)] \
        + [new.law]
    halves = [law.half_length(old.mech if m == 0 else mech) for m, law in enumerate(laws)]
    exit_r = halves[0]
    state = old.evaluate(exit_r)
    limits = new.drive.effective(mech)

    def torque_terms(th: FloatArray) -> TorqueTerms:
        return new.drive.torque_terms(mech, th)

    parts: list[tuple[Piecewise, float, float]] = []
    r = exit_r
    for m in range(1, plants + 1):
        entry_r = at[m] - halves[m]
        length = entry_r - r
        if not length > 1e-6 * gaps[m - 1]:
            raise CamInputError('spacing', gaps[m - 1], f'> {halves[m - 1]:.6g} m + '
                                f'{halves[m]:.6g} m (the soil arcs either side of the change)')
        end = laws[m].edge_state(mech, -1) if m < plants else new.edge_state(-1)
        end = (end[0] + TWO_PI * m, end[1], end[2])
        arc, _ = plan_arc(ArcEnds(length, state, end), max(new.speed, 1e-3), limits,
                          torque_terms, ARC_PIECES)
        parts.append((arc, r, 0.0))
        if m < plants:
            soil = soil_arc(mech, laws[m])
            parts.append((soil, entry_r, TWO_PI * m))
            r = at[m] + halves[m]
            th, d1, d2 = soil.at(soil.end)
            state = (th + TWO_PI * m, d1, d2)
        else:
            r = entry_r
    piecewise = _placed(parts)
    # the stretch judged: the old plant's soil arc, the transition, one period of the new
    old_soil = soil_arc(old.mech, old.law)
    stretch = _placed([(old_soil, -halves[0], 0.0), (piecewise, exit_r, 0.0),
                       (new.period, r, TWO_PI * plants)])
    windows = [(-halves[0], at[-1] + d - halves[-1])]
    return gaps, piecewise, stretch, windows


def _thermal(figures: LoadFigures, stretch_length: float, old: CamProfile, new: CamProfile,
             speed: float) -> LoadFigures:
    """The transition's figures with the RMS torque over the drive's thermal window (the
    rated torque is a thermal limit): the heat of the stretch (the old last plant's soil entry
    to the end of the new profile's first own plant) plus, for the rest of the window, the
    hotter of the two steady profiles'."""
    window = max(speed * new.drive.thermal_window, stretch_length)
    steady = max(old.figures(speed).rms_torque, new.figures(speed).rms_torque)
    heat = figures.rms_torque ** 2 * stretch_length + steady ** 2 * (window - stretch_length)
    rms = math.sqrt(heat / window)
    limit = new.drive.effective(new.mech).rms_torque
    return replace(figures, rms_torque=rms,
                               utilisation={**figures.utilisation, 'rms torque': rms / limit})


def plan_transition(old: CamProfile, new: CamProfile) -> Transition:
    """The transition from profile `old` to profile `new` (a `Transition`), checked against
    the drive's limits at the new profile's planning speed and spread over as few plants as
    keep it within them (module doc); cached. CamLimitError when even
    `MAX_TRANSITION_PLANTS` plants do not (the figure and the limit named), CamInputError when
    the soil arcs either side leave no room for an arc."""
    known = _known(old, new)
    if known is not None:
        return known
    if old.law.same_as(new.law) and old.mech == new.mech:
        out = Transition(fingerprint(old), fingerprint(new), (new.spacing,), None, None,
                         new.speed)
        remember_transition(out)
        return out
    speed = max(new.speed, 1e-3)
    first: LoadFigures | None = None
    figures: LoadFigures | None = None
    no_room: CamInputError | None = None
    for plants in range(1, MAX_TRANSITION_PLANTS + 1):
        try:
            gaps, piecewise, stretch, windows = _spread(old, new, plants)
        except CamInputError as exc:        # no room for an arc: more plants may give it
            no_room = no_room or exc
            continue
        figures = _thermal(LoadSamples(stretch, new.spacing, new.mech, new.drive,
                                       windows).figures(speed),
                           windows[0][1] - windows[0][0], old, new, speed)
        first = first or figures
        if figures.feasible:
            out = Transition(fingerprint(old), fingerprint(new), gaps, piecewise, figures,
                             new.speed)
            remember_transition(out)
            return out
    if first is None or figures is None:
        assert no_room is not None, 'every spread either raised or gave figures'
        raise no_room
    raise CamLimitError.from_message(
        f'the change from {_named(old)} to {_named(new)} cannot be made within the drive\'s '
        f'limits: {first.over_text()} in one plant, {figures.over_text()} spread over '
        f'{MAX_TRANSITION_PLANTS} plants')


def _named(profile: CamProfile) -> str:
    return f'{profile.law.name or "a law"} at {profile.spacing:.4g} m'


class _Periodic:
    """A profile placed on the row: its plant j at origin + j·d has θ = π + 2π(turn + j)."""

    __slots__ = ('profile', 'origin', 'turn', '_offset')

    def __init__(self, profile: CamProfile, origin: float, turn: int) -> None:
        self.profile, self.origin, self.turn = profile, float(origin), int(turn)
        self._offset = TWO_PI * self.turn

    def evaluate(self, s: float) -> State:
        th, d1, d2 = self.profile.evaluate(s - self.origin)
        return th + self._offset, d1, d2

    def values(self, s: FloatArray, order: int) -> FloatArray:
        out = self.profile.values(s - self.origin, order)
        return out + self._offset if order == 0 else out


class _Arc:
    """A transition θ(r) placed on the row: r = s − s0, θ raised by `offset`."""

    __slots__ = ('piecewise', 's0', 'offset')

    def __init__(self, piecewise: Piecewise, s0: float, offset: float = 0.0) -> None:
        self.piecewise, self.s0, self.offset = piecewise, float(s0), float(offset)

    def evaluate(self, s: float) -> State:
        th, d1, d2 = self.piecewise.at(s - self.s0)
        return th + self.offset, d1, d2

    def values(self, s: FloatArray, order: int) -> FloatArray:
        out = self.piecewise.values(s - self.s0, order)
        return out + self.offset if order == 0 else out


class _Plants:
    """The planting instants of one profile on the row: origin + j·d for first ≤ · ≤ last."""

    __slots__ = ('periodic', 'first', 'last')
    transitional = False

    def __init__(self, periodic: _Periodic, first: float, last: float = math.inf) -> None:
        self.periodic, self.first, self.last = periodic, first, last

    def after(self, s: float) -> tuple[float, int] | None:
        """(s_plant, θ turn) of this profile's first plant strictly after s, or None."""
        p = self.periodic
        d = p.profile.spacing
        if s < self.first:
            j = round((self.first - p.origin) / d)
        else:
            j = math.floor((s - p.origin) / d) + 1
            while p.origin + (j - 1) * d > s:
                j -= 1
            while p.origin + j * d <= s:
                j += 1
        at = p.origin + j * d
        return (at, p.turn + j) if at <= self.last else None


class _Listed:
    """A transition's own plants (after its first, before the new profile's): at the given
    distances, θ = π + 2π·turn each; a change waits for them (`transitional`)."""

    __slots__ = ('periodic', 'at', 'turns', 'last')
    transitional = True

    def __init__(self, periodic: _Periodic, at: Sequence[float], turns: Sequence[int]) -> None:
        self.periodic, self.at, self.turns = periodic, list(at), list(turns)
        self.last = math.inf

    def after(self, s: float) -> tuple[float, int] | None:
        for at, turn in zip(self.at, self.turns):
            if at > s and at <= self.last:
                return at, turn
        return None


_Segment = _Periodic | _Arc          # a stretch of the track: a placed profile or an arc
_PlantRun = _Plants | _Listed         # the planting instants of one stretch


class CamTrack:
    """θ(s) of one row across spacing changes (module doc)."""

    def __init__(self, profile: CamProfile, origin: float = 0.0, turn: int = 0) -> None:
        first = _Periodic(profile, origin, turn)
        self._starts = [-math.inf]
        self._segments: list[_Segment] = [first]
        self._plants: list[_PlantRun] = [_Plants(first, -math.inf)]

    @property
    def joins(self) -> list[float]:
        """Distances (m) where one piece of the track hands over to the next (the old
        profile's soil exit, a transition arc's end) — where a change could show a jump."""
        return list(self._starts[1:])

    def segment_values(self, index: int, s: float) -> State:
        """(θ, θ′, θ″) of the track's segment `index` (0 = the first) at s, even outside the
        stretch where it is in force: the left and right limits at a join."""
        return self._segments[index].evaluate(s)

    @property
    def profile(self) -> CamProfile:
        """The profile in force last (the newest change)."""
        return self._plants[-1].periodic.profile

    def evaluate(self, s: float) -> State:
        """(θ, θ′, θ″) at the row's travelled distance s (m): rad, rad/m, rad/m²."""
        return self._segments[bisect_right(self._starts, s) - 1].evaluate(s)

    def motion(self, s: float, ground_speed: float,
               ground_acceleration: float = 0.0) -> tuple[float, float, float]:
        """(θ, ω, α) the sun bar must have at the row's distance s (m), ground speed (m/s)
        and acceleration (m/s²): the CSP target and its feed-forwards (rad, rad/s, rad/s²)."""
        return sun_bar_motion(self.evaluate(s), ground_speed, ground_acceleration)

    def values(self, s: ArrayLike, order: int = 0) -> FloatArray:
        """θ (order 0) or its derivative (1..3) at an array of s (numpy; plots, checks)."""
        at = np.asarray(s, dtype=np.float64)
        which = np.searchsorted(self._starts, at, side='right') - 1
        out = np.empty_like(at)
        for i in np.unique(which).tolist():
            mine = which == i
            out[mine] = self._segments[i].values(at[mine], order)
        return out

    def next_plant(self, s: float) -> tuple[float, CamProfile]:
        """(s_plant, profile) of the first planting instant strictly after s."""
        best: tuple[float, _PlantRun] | None = None
        for plants in self._plants:
            hit = plants.after(s)
            if hit is not None and (best is None or hit[0] < best[0]):
                best = (hit[0], plants)
        if best is None:
            raise AssertionError('the profile in force last plants without end')
        return best[0], best[1].periodic.profile

    def plants(self, s0: float, s1: float) -> list[tuple[float, float]]:
        """Planting instants (s, θ) in [s0, s1], in order."""
        out: list[tuple[float, float]] = []
        s = math.nextafter(s0, -math.inf)
        while True:
            at, _ = self.next_plant(s)
            if at > s1:
                return out
            out.append((at, self.evaluate(at)[0]))
            s = at

    def _change_point(self, s_now: float) -> tuple[float, int, int]:
        """(s_k, θ turn, index into the plants) of the plant a change asked at s_now follows:
        the next planting instant, not one of a transition still under way."""
        best: tuple[float, int, int] | None = None
        for index, plants in enumerate(self._plants):
            if plants.transitional:
                continue
            hit = plants.after(s_now)
            if hit is not None and (best is None or hit[0] < best[0]):
                best = (hit[0], hit[1], index)
        if best is None:
            raise AssertionError('the profile in force last plants without end')
        return best

    def transition(self, profile: CamProfile, s_now: float) -> Transition:
        """The `Transition` a change to `profile` asked at s_now would take (planned, or found
        planned), changing nothing; CamLimitError / CamInputError as `change` would raise."""
        index = self._change_point(s_now)[2]
        return plan_transition(self._plants[index].periodic.profile, profile)

    def change(self, profile: CamProfile, s_now: float) -> float:
        """Switch to `profile` at the next planting instant after `s_now` (module doc).
        Returns s_k, the old spacing's last plant; the new spacing's first is at s_k + d′
        (later when the change is spread over more plants). CamLimitError (the track
        unchanged) when no transition within the drive's limits exists. A change asked while
        an earlier one's transition is under way takes effect once that is done."""
        s_k, turn, index = self._change_point(s_now)
        old = self._plants[index].periodic
        transition = plan_transition(old.profile, profile)
        exit_s = s_k + old.profile.law.half_length(old.profile.mech)
        at = [s_k]
        for gap in transition.gaps:
            at.append(at[-1] + gap)
        k = transition.plants
        new = _Periodic(profile, at[k], turn + k)
        segments: list[tuple[float, _Segment]] = []
        if transition.piecewise is None:
            segments.append((exit_s, new))
        else:
            arc = transition.piecewise
            segments += [(s_k + arc.start, _Arc(arc, s_k, TWO_PI * turn)),
                         (s_k + arc.end, new)]
        # everything from the old exit on is replaced (an earlier change not yet in force too)
        keep = bisect_left(self._starts, exit_s)
        if self._segments[keep - 1] is not old:
            raise AssertionError('the next plant is not in force at its own soil exit')
        del self._starts[keep:], self._segments[keep:]
        for start_s, segment in segments:
            self._starts.append(start_s)
            self._segments.append(segment)
        self._plants = [p for p in self._plants[:index + 1]]
        self._plants[index].last = s_k
        if k > 1:
            self._plants.append(_Listed(new, at[1:k], [turn + m for m in range(1, k)]))
        self._plants.append(_Plants(new, at[k]))
        return s_k
