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

`evaluate(s)` is the per-cycle call: a bisect over the few segments, then the profile's own
evaluation. Pure Python floats; no ROS.
"""

from bisect import bisect_left, bisect_right
import math

from planter_ros.kinematics.five_bar import TWO_PI

from .arc import ARC_PIECES, plan_arc
from .drive import sun_bar_motion
from .errors import CamInputError

__all__ = ['CamTrack']


class _Periodic:
    """A profile placed on the row: its plant j at origin + j·d has θ = π + 2π(turn + j)."""

    __slots__ = ('profile', 'origin', 'turn', '_offset')

    def __init__(self, profile, origin, turn):
        self.profile, self.origin, self.turn = profile, float(origin), int(turn)
        self._offset = TWO_PI * self.turn

    def evaluate(self, s):
        th, d1, d2 = self.profile.evaluate(s - self.origin)
        return th + self._offset, d1, d2

    def values(self, s, order):
        out = self.profile.values(s - self.origin, order)
        return out + self._offset if order == 0 else out


class _Arc:
    """A transition arc starting at s0."""

    __slots__ = ('piecewise', 's0')

    def __init__(self, piecewise, s0):
        self.piecewise, self.s0 = piecewise, float(s0)

    def evaluate(self, s):
        return self.piecewise.at(s - self.s0)

    def values(self, s, order):
        return self.piecewise.values(s - self.s0, order)


class _Plants:
    """The planting instants of one profile on the row: origin + j·d for first ≤ · ≤ last."""

    __slots__ = ('periodic', 'first', 'last')

    def __init__(self, periodic, first, last=math.inf):
        self.periodic, self.first, self.last = periodic, first, last

    def after(self, s):
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


class CamTrack:
    """θ(s) of one row across spacing changes (module doc)."""

    def __init__(self, profile, origin=0.0, turn=0):
        first = _Periodic(profile, origin, turn)
        self._starts = [-math.inf]
        self._segments = [first]
        self._plants = [_Plants(first, -math.inf)]

    @property
    def joins(self):
        """Distances (m) where one piece of the track hands over to the next (the old
        profile's soil exit, a transition arc's end) — where a change could show a jump."""
        return list(self._starts[1:])

    def segment_values(self, index, s):
        """(θ, θ′, θ″) of the track's segment `index` (0 = the first) at s, even outside the
        stretch where it is in force: the left and right limits at a join."""
        return self._segments[index].evaluate(s)

    @property
    def profile(self):
        """The profile in force last (the newest change)."""
        return self._plants[-1].periodic.profile

    def evaluate(self, s):
        """(θ, θ′, θ″) at the row's travelled distance s (m): rad, rad/m, rad/m²."""
        return self._segments[bisect_right(self._starts, s) - 1].evaluate(s)

    def motion(self, s, ground_speed, ground_acceleration=0.0):
        """(θ, ω, α) the sun bar must have at the row's distance s (m), ground speed (m/s)
        and acceleration (m/s²): the CSP target and its feed-forwards (rad, rad/s, rad/s²)."""
        return sun_bar_motion(self.evaluate(s), ground_speed, ground_acceleration)

    def values(self, s, order=0):
        """θ (order 0) or its derivative (1..3) at an array of s (numpy; plots, checks)."""
        import numpy as np
        s = np.asarray(s, dtype=float)
        which = np.searchsorted(self._starts, s, side='right') - 1
        out = np.empty_like(s)
        for i in np.unique(which):
            mine = which == i
            out[mine] = self._segments[i].values(s[mine], order)
        return out

    def next_plant(self, s):
        """(s_plant, profile) of the first planting instant strictly after s."""
        best = None
        for plants in self._plants:
            hit = plants.after(s)
            if hit is not None and (best is None or hit[0] < best[0]):
                best = (hit[0], hit[1], plants)
        return best[0], best[2].periodic.profile

    def plants(self, s0, s1):
        """Planting instants (s, θ) in [s0, s1], in order."""
        out = []
        s = math.nextafter(s0, -math.inf)
        while True:
            at, _ = self.next_plant(s)
            if at > s1:
                return out
            out.append((at, self.evaluate(at)[0]))
            s = at

    def change(self, profile, s_now):
        """Switch to `profile` at the next planting instant after `s_now` (module doc).
        Returns s_k, the old spacing's last plant; the new spacing's first is at s_k + d′."""
        best = None
        for index, plants in enumerate(self._plants):
            hit = plants.after(s_now)
            if hit is not None and (best is None or hit[0] < best[0]):
                best = (hit[0], hit[1], index)
        s_k, turn, index = best
        old = self._plants[index].periodic
        exit_s = s_k + old.profile.law.half_length(old.profile.mech)
        origin = s_k + profile.spacing
        entry_s = origin - profile.entry
        new = _Periodic(profile, origin, turn + 1)
        segments = []
        if old.profile.law.same_as(profile.law) and old.profile.mech == profile.mech:
            segments.append((exit_s, new))
        else:
            length = entry_s - exit_s
            if not length > 1e-6 * profile.spacing:
                raise CamInputError('spacing', profile.spacing, f'> {exit_s - s_k:.6g} m + '
                                    f'{profile.entry:.6g} m (the soil arcs either side of the '
                                    'change)')
            start = old.evaluate(exit_s)
            end_th, end_d1, end_d2 = profile.edge_state(-1)
            end = (end_th + TWO_PI * (turn + 1), end_d1, end_d2)
            limits = profile.drive.effective(profile.mech)
            arc, _ = plan_arc(length, start, end, max(profile.speed, 1e-3), limits,
                              lambda th: profile.drive.torque_terms(profile.mech, th),
                              ARC_PIECES)
            segments += [(exit_s, _Arc(arc, exit_s)), (entry_s, new)]
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
        self._plants.append(_Plants(new, origin))
        return s_k
