"""What the command engine does about the faults a real CAN bus has (doc/command.md, "Faults
and their recovery"), per row, as plain state the engine steps: no CAN and no threads here.

* **Halts and the plants they cost**: a row's halt (any cause but "not enabled yet") opens an
  episode; it closes once the row is back in step with its grid (phase error under
  `BACK_IN_STEP` of a plant pitch for `STEADY` s: by angle, not by the shaft's speed, which
  jitters with the SYNC interpolation). The plants
  missed are the whole pitches the phase lock gave up meanwhile (its slips): by angle, the
  mechanism set exactly that many plants fewer than the grid asked for.
* **A bus that failed** (send errors, bus-off, receive errors): a row that halted while the bus
  failed, or within `BUS_WINDOW` s after, for a communication cause (its watchdog quick-stopped
  it: EMCY 81xxh / 8250h, it left OPERATION ENABLED, its heartbeat was lost) is re-enabled once
  the bus is back (`BUS_QUIET` s without an error) and its heartbeat is fresh: at most
  `AUTO_RESETS` fault resets per episode. A drive fault of its own (anything else) waits for the
  operator's reset, as always; so does a drive whose heartbeat vanished on a healthy bus.
* **EMCY storms**: every EMCY is counted; the first of a burst is logged, then at most one line
  per `EMCY_LOG_PERIOD` s with how many came.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
import math
import threading

from planter_ros.control import sync_status
from planter_ros.control.sync_status import Halt

from .reports import Recovery

__all__ = ['AUTO_RESETS', 'BACK_IN_STEP', 'BUS_QUIET', 'BUS_WINDOW', 'EMCY_LOG_PERIOD',
           'Episode', 'RowRecovery', 'communication_fault']

BACK_IN_STEP = 0.05       # share of a plant pitch: the row is back on its grid
STEADY = 0.5              # s the row stays back in step before the episode closes
EPISODE_LIMIT = 60.0      # s: an episode not back in step by then is closed as it stands
BUS_WINDOW = 1.0          # s after a bus error a halt still counts as caused by it
BUS_QUIET = 0.3           # s without a bus error: the bus is back
AUTO_RESETS = 3           # fault resets tried per episode caused by the bus
EMCY_LOG_PERIOD = 1.0     # s between two log lines about a row's EMCYs
RECONFIGURE_RETRY = 1.0   # s between two attempts to configure a restarted drive again
PROBE_AFTER = 1.0         # s a lost heartbeat lasts before we ask the drive whether it restarted
PROBE_RETRY = 0.5         # s between two such questions (each waits 0.2 s at most)


def communication_fault(halt: Halt | None, error_code: int, reason: str) -> bool:
    """The halt is what a drive's communication watchdog, or our view of its heartbeat, does
    when frames stop: EMCY 81xxh (communication) or 8250h (RPDO deadline), a drive that left
    OPERATION ENABLED (its quick stop), a lost heartbeat."""
    if halt is None or halt.kind != sync_status.FAULTED:
        return False
    return (error_code & 0xFF00 == 0x8100 or error_code == 0x8250
            or reason.startswith('drive left OPERATION ENABLED')
            or reason == 'drive heartbeat lost')


@dataclass
class Episode:
    """A row's halt, from its first moment until the row is back in step."""

    since: float                     # monotonic s
    cause: str                       # the first halt's text
    slips: int                       # the law's phase slips when it began
    bus: bool = False                # it began while (or just after) the bus failed
    restarted: bool = False          # the drive restarted during it (boot-up, pre-operational)
    resets: int = 0                  # automatic fault resets tried
    resumed: float | None = None     # when the drive was commanded again
    steady_since: float | None = None


@dataclass
class RowRecovery:
    """One row's recovery state and counts (see the module doc)."""

    episode: Episode | None = None
    recoveries: deque[Recovery] = field(default_factory=lambda: deque(maxlen=20))  # closed
    plants_missed: int = 0
    restarts: int = 0                # the drive restarted and was configured again
    auto_resets: int = 0
    reconfiguring: bool = False      # a worker thread configures the drive again
    next_reconfigure: float = 0.0
    reconfigure_error: str = ''
    probing: bool = False            # a worker asks the drive whether it restarted
    worker: threading.Thread | None = None   # the thread doing either (joined at shutdown)
    next_probe: float = 0.0
    next_auto_reset: float = 0.0
    resumed: bool = False            # frames start again: their pause is no loop gap
    emcy_count: int = 0              # EMCYs seen (the drive master's count)
    emcy_logged: int = 0             # that count at the last log line
    emcy_log_at: float = -math.inf

    def halted(self, now: float, halt: Halt, slips: int, bus_trouble: bool) -> None:
        """The row is halted at `now` (each step it is)."""
        if self.episode is None:
            self.episode = Episode(now, halt.text, slips, bus=bus_trouble)
        elif bus_trouble:
            self.episode.bus = True
        if halt.kind == sync_status.RESTARTED:
            self.episode.restarted = True
        self.episode.resumed = None
        self.episode.steady_since = None

    def running(self, now: float, in_step: bool, slips: int) -> Recovery | None:
        """The row is commanded at `now`; `in_step`: on its grid. Returns
        the closed episode's record once the row has been in step for `STEADY` s."""
        episode = self.episode
        if episode is None:
            return None
        if episode.resumed is None:
            episode.resumed = now
        if in_step:
            episode.steady_since = now if episode.steady_since is None else \
                episode.steady_since
        else:
            episode.steady_since = None
        steady = episode.steady_since is not None and now - episode.steady_since >= STEADY
        if not steady and now - episode.since < EPISODE_LIMIT:
            return None
        missed = max(slips - episode.slips, 0)
        record = Recovery(episode.cause, episode.restarted, episode.bus,
                          halted_s=round(episode.resumed - episode.since, 3),
                          back_in_step_s=round((episode.steady_since or now) - episode.since, 3),
                          plants_missed=missed, in_step=steady, auto_resets=episode.resets)
        self.plants_missed += missed
        self.recoveries.append(record)
        self.episode = None
        return record

    def emcy_line(self, now: float, count: int, code: int) -> str | None:
        """A log line about the EMCYs counted up to `count` (last `code`), or None: the first
        of a burst at once, then at most one line per EMCY_LOG_PERIOD."""
        self.emcy_count = count
        new = count - self.emcy_logged
        previous = self.emcy_log_at
        if new <= 0 or now - previous < EMCY_LOG_PERIOD:
            return None
        self.emcy_logged, self.emcy_log_at = count, now
        if new == 1 and now - previous > 2 * EMCY_LOG_PERIOD:
            return f'EMCY 0x{code:04X} from the drive'
        span = (f'in the last {now - previous:.1f} s' if math.isfinite(previous)
                else 'since start')
        return (f'{new} EMCY from the drive {span} (last 0x{code:04X}, {count} in all): '
                'logged at most once a second')
