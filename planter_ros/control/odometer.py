"""The row's travelled distance from its ground-speed samples (the distance a phase lock's grid
and the monitor's plants are placed along): a sample is the speed at its instant, the distance
the trapezoid of the samples, without the half-interval lag of holding each speed."""
from __future__ import annotations

__all__ = ['Odometer']


class Odometer:
    """Travelled distance s (m) at any instant from speed samples; a sample older than
    `timeout` s (the ground-speed timeout: PhaseLockConfig.ground_speed_timeout) is stale and
    its speed held no longer."""

    def __init__(self, timeout: float) -> None:
        self.timeout = timeout
        self.speed = 0.0                       # the newest sample's forward speed (m/s)
        self.stamp: float | None = None        # its time (s), None before the first
        self._s = 0.0                          # travelled distance at `stamp` (m)
        # the trapezoid's correction still to take (m): (pending, the part taken over the
        # `window` s after `stamp`, window); sample()
        self._catch = (0.0, 0.0, 0.0)

    def sample(self, v: float, now: float) -> None:
        """Take a speed sample already judged plausible (m/s; ≤ 0 = not moving forward).

        Holding each speed until the next sample lags the trapezoid by half a sample interval
        (25 ms at 20 Hz: every plant after a 0.1 m/s speed change sat 2.5 mm further on,
        measured in the demo; doc/command.md). So the distance runs at the newest speed plus
        the trapezoid's correction of the last interval (½·(v_k − v_{k−1})·Δt), spread over
        the next interval of that length: continuous, no lag (the second-order Adams-Bashforth
        step), and the correction's noise does not add up (its sum telescopes). The distance
        never runs backwards: a correction the speed cannot take (a stop) waits for the next
        sample. No correction across a stale gap."""
        v = max(float(v), 0.0)
        s = self.travelled(now)
        catch = window = 0.0
        if self.stamp is not None:
            span = now - self.stamp
            if 0.0 < span <= self.timeout:
                catch = self._catch[0] - self._caught(span) + 0.5 * (v - self.speed) * span
                # over the interval just seen, or what was left of the last correction's
                # window: a sample soon after a long gap does not squeeze the gap's correction
                # into its own short interval
                window = max(span, self._catch[2] - span)
        self._s, self.speed, self.stamp = s, v, now
        self._catch = (catch, max(catch, -v * window), window) if catch else (0.0, 0.0, 0.0)

    def _caught(self, held: float) -> float:
        """The part of the pending correction taken `held` s after the newest sample (m)."""
        _, usable, window = self._catch
        if not usable or window <= 0.0:
            return 0.0
        return usable * min(held / window, 1.0)

    def stale(self, now: float) -> bool:
        """No sample yet, or the newest older than the timeout."""
        return self.stamp is None or now - self.stamp > self.timeout

    def travelled(self, now: float) -> float:
        """Travelled distance s (m): accepted speeds held for at most the timeout."""
        if self.stamp is None:
            return self._s
        held = min(max(now - self.stamp, 0.0), self.timeout)
        return self._s + self.speed * held + self._caught(held)

    def rate(self, now: float) -> float:
        """The speed the distance runs at now (m/s): the newest sample's plus the pending
        trapezoid correction's rate."""
        _, usable, window = self._catch
        if usable and window > 0.0 and self.stamp is not None and now - self.stamp < window:
            return self.speed + usable / window
        return self.speed
