"""The demo's verdict: one line, PASS or FAIL with every reason, and the exit code it gives.

A run passes when the machine did what it is for and left a record of it:
* no drive watchdog tripped (the command path kept the drives' RPDO deadline and heartbeat);
* no drive fault (EMCY, fault bit, lost drive heartbeat) and every row's drive was enabled;
* every planting row placed at least two plants, and its spacing error RMS (gap − d, each gap
  against the design in force when its plant was set) is at most SPACING_TOLERANCE of d;
* no node changed the design during the run (the demo's own design node publishes once);
* the bag was recorded, finalised and replays;
* every drive ended disabled (no torque) at standstill, however the run was stopped;
* the crop planted well: every row's ISO 7256-1 indices, uprightness rate and hole width,
  from the replay of the bag, within the crop's acceptance limits (the scene's, recorded in
  the bag: prediction.acceptance); each failure names the row, the index, its value and limit.
Pure: no ROS import.
"""

from dataclasses import dataclass, field

from planter_ros.prediction.acceptance import acceptance_failures

__all__ = ['EXIT_FAIL', 'EXIT_PASS', 'RowResult', 'RunOutcome', 'SPACING_TOLERANCE', 'Verdict',
           'judge']

# per-row spacing error RMS, as a fraction of d. The demo is the real node graph in real time
# on whatever host runs it: DDS delivery and scheduling jitter put a loaded 2-core host's runs
# at 1–2.6 % of d, while what the verdict is for (a cross-talking graph, another design, a
# tripped or stalled drive) gives tens of %. The closed-loop bench holds the 2 % bar.
SPACING_TOLERANCE = 0.05
EXIT_PASS, EXIT_FAIL = 0, 1


@dataclass
class RowResult:
    """One planting row's figures from the demo's own measurement."""

    label: str
    plants: int
    rms: float                    # spacing error RMS relative to d (fraction)


@dataclass(frozen=True)
class RunOutcome:
    """What the demo itself saw of a run, beside the sync process's report: why the drives did
    not start ('' = they did), why there is no usable bag ('' = there is one), the monitor's
    account of design changes ('' = none), the design changes the scene's spacing schedule
    made (not a fault), and whether the field run began (False: stopped before it; nothing
    planted: the rows and the crop are not judged, the drives and the bag are)."""

    start_error: str = ''
    bag_error: str = ''
    monitor_design_changes: str = ''
    scheduled_changes: int = 0
    field_run: bool = True


@dataclass
class Verdict:
    reasons: list = field(default_factory=list)
    stopped_by: str = ''          # 'SIGTERM' / 'SIGINT' when a signal ended the run early
    elapsed: float = 0.0          # s of field run

    @property
    def passed(self):
        return not self.reasons

    @property
    def exit_code(self):
        return EXIT_PASS if self.passed else EXIT_FAIL

    def line(self):
        stopped = (f' (stopped by {self.stopped_by} after {self.elapsed:.1f} s)'
                   if self.stopped_by else '')
        if self.passed:
            return (f'verdict: PASS{stopped}: no watchdog trip, no drive fault, spacing error '
                    f'RMS (true distance) <= {100 * SPACING_TOLERANCE:g} % of d on every row, '
                    "design unchanged, bag recorded, every row within the crop's acceptance "
                    'limits')
        return f'verdict: FAIL{stopped}: ' + '; '.join(self.reasons)


def judge(rows, sync_report, outcome=RunOutcome(), acceptance=None):
    """The verdict of a run. `rows`: RowResult per planting row (empty if the run never
    started); `sync_report`: the sync process's final report (sync_process.final_report, None if
    it never came); `outcome`: what the demo saw of the run (RunOutcome); `acceptance`: the
    replay's judgement of the bag by the crop's limits (prediction.judge_acceptance; None: no
    replay, `outcome.bag_error` says why)."""
    start_error, bag_error = outcome.start_error, outcome.bag_error
    field_run = outcome.field_run
    reasons = []
    if start_error:
        reasons.append(f'drives not started: {start_error}')
    if sync_report is None and not start_error:
        reasons.append('the sync process gave no report')
    if sync_report is not None:
        reasons += _command_path_reasons(sync_report)
    if not start_error and field_run:
        for row in rows:
            name = f'row {row.label}' if row.label else 'the row'
            if row.plants < 2:
                reasons.append(f'{name} placed {row.plants} plant(s): spacing not judged '
                               '(needs 2)')
            elif row.rms > SPACING_TOLERANCE:
                reasons.append(f'{name} spacing error RMS {100 * row.rms:.2f} % of d > '
                               f'{100 * SPACING_TOLERANCE:g} % (true distance)')
    sources = sync_report.design if sync_report is not None else None   # who set the design
    if sources is not None and sources.changes > outcome.scheduled_changes:
        reasons.append(f'design changed by another node during the run ({sources.changes}x, '
                       f'the latest from {sources.last_change})')
    elif outcome.monitor_design_changes:
        reasons.append(f'design changed by another node during the run '
                       f'({outcome.monitor_design_changes})')
    if bag_error:
        reasons.append(f'no bag: {bag_error}')
    if not start_error and field_run:
        reasons += [f'below the crop\'s limits: {text}' for text in
                    acceptance_failures(acceptance)]
    return Verdict(reasons)


def _command_path_reasons(report):
    """Watchdog trips, drive faults, rows left out, and a drive the run did not leave disabled
    at standstill (sync_process.SyncReport)."""
    reasons = []
    trips = report.drives.watchdog_trips
    if trips:
        reasons.append('drive watchdog trip: ' + ', '.join(
            f'node {node} {why} (EMCY 0x{code:04X})' for node, why, code in trips))
    for row in (report.command.rows if report.command is not None else []):
        name = f'row {row.label}' if row.label else 'the drive'
        if row.left_out:
            reasons.append(f'{name} left out: {row.left_out}')
        elif row.faults:
            missed = row.plants_missed
            reasons.append(f'drive fault on {name} ({row.faults}x, last: {row.last_fault}'
                           + (f'; {missed} plant(s) missed' if missed else '') + ')')
    for node, end in sorted(report.drives.end.items(), key=lambda item: int(item[0])):
        if not (end.disabled and end.at_standstill):
            reasons.append(f'drive node {node} not left disabled at standstill: {end.text()}')
    return reasons
