"""Test set-up shared by every test module.

DDS discovery must stay on loopback in this workplace (and in CI), and each test session gets a
DDS domain of its own: both are set here, before any test module can call rclpy.init().

Real-time tests: a test that passes only when scheduled in real time (a live ROS graph or node,
a simulated drive and its master, a `planter demo` run, commissioning, signal and process-death
timings) carries the marker `realtime`: `pytestmark = pytest.mark.realtime` at the top of its
module, `@pytest.mark.realtime` on one test, or `pytest.param(..., marks=pytest.mark.realtime)`
on one case. That is the only list. With five processes (pytest.ini), two of them take the
real-time tests first, one test after the other on each (as in a serial run; a module's tests
that share a fixture made once stay together): first those whose live part runs in processes
of their own (a demo run and the like, whose command process and simulated drives run
SCHED_FIFO as on the machine), two at once; then those live in the test process itself (nodes,
simulated drives and their loops; a command loop at the command process's SCHED_FIFO priority
while it runs, the rest without real-time priority: `live_where`), on the third process as
well, up to three at once, never beside a demo-like one (beside those a node's in-process
drive once missed its speed by 5 %). The other processes run the rest meanwhile at
`BACKGROUND_NICE` above the priority the session started with, so they never starve them;
each lane joins them once its real-time tests are done. No process of the suite ever runs above
the priority the session was started with, but for that command loop under test, at the
priority the product gives it. A test that uses a live fixture
(`LIVE_FIXTURES`: `ros`, `sim`, `channel`, `make_drive`, ...) or starts something live
(`LIVE_NAMES`: a demo run, a node, a simulated bus, rclpy) without the marker fails, naming
the marker: a new module cannot be forgotten.

A real-time test that fails while the host itself left every process unscheduled for more than
host_stalls.STARVED s runs once more (host_stalls.py). Nothing hides it: the first run's failure
and the stall are in the terminal summary and, as properties of the test, in the JUnit file;
and when more than one test of a session needed it, the session fails. No other re-run: a test
marked `flaky` fails and `--reruns` is refused (pytest-rerunfailures comes with colcon).
test_harness.py tests all of this on small test files.
"""
from fnmatch import fnmatch
import gc
import hashlib
import json
import os
import sys
import time
import types
from pathlib import Path

import pytest

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

# Every test graph runs in a DDS domain of this test session's own: a second test run, a demo
# or any other ROS process on the host can neither see nor disturb it.
from planter_ros.host.dds_domain import isolate_environment  # noqa: E402

isolate_environment()

# CI runs the property tests derandomized: the same examples every run, so a red build is a
# reproducible finding, not luck; locally they keep exploring new examples.
from hypothesis import settings  # noqa: E402

settings.register_profile('ci', derandomize=True)
if os.environ.get('CI'):
    settings.load_profile('ci')

# the rclpy fixture (a fresh Context and executor per test), for every test module
from ros_fixtures import ros  # noqa: E402, F401
# the watcher of host stalls (a real-time test that failed meanwhile runs once more)
import host_stalls  # noqa: E402
# the CAN drive fixtures (a virtual channel per test, the simulated drive, masters)
from drive_helpers import channel, enabled, make_drive, sim, spy  # noqa: E402, F401
# the rice three-arm scene and its mechanism (module scope), for the three-arm test modules
from three_arm_fixtures import mech, params  # noqa: E402, F401


# fixtures that bring up something live: a test that uses one (directly or through another
# fixture) must be marked realtime
LIVE_FIXTURES = frozenset({'ros', 'sim', 'channel', 'spy', 'make_drive', 'enabled'})
# names whose use in a test (or in a fixture it uses) starts something live: a demo run
# (test_demo.start_demo, or run_planter('demo', ... '--duration' ...)), a node, a simulated
# drive or its bus, an rclpy context of the test's own
LIVE_NAMES = frozenset({'start_demo', 'SyncNode', 'MonitorNode', 'DesignNode',
                        'create_node', 'Context', 'SimulatedBus', 'SimulatedDrive',
                        'SimProcess'})
# of those, the names whose live part runs in the test's own process (the others start
# processes of their own: a demo run, the simulated drives' process); and a master's or the
# command engine's loop run by the test itself
LIVE_HERE_NAMES = LIVE_NAMES - {'start_demo', 'SimProcess'} | {'CommandEngine', 'run_engine',
                                                                 'Cia402Drive'}
REALTIME = 'realtime'
HERE, APART = 'here', 'apart'     # a real-time test live in its own process, or in others
BACKGROUND_NICE = 10       # the other tests' nice value, added to the session's
START_NICE = os.getpriority(os.PRIO_PROCESS, 0)    # the priority this process started with

_UNMARKED = pytest.StashKey[str]()
_KINDS = pytest.StashKey[dict]()


def _realtime(item):
    return item.get_closest_marker(REALTIME) is not None


def _module(nodeid):
    return nodeid.split('::', 1)[0]


def _names(code):
    """(The names, the string constants) a code object and those nested in it use; a dotted
    module name imported counts by its first part as well."""
    names = set(code.co_names) | {name.split('.', 1)[0] for name in code.co_names}
    strings = {c for c in code.co_consts if isinstance(c, str)}
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            more = _names(const)
            names |= more[0]
            strings |= more[1]
    return names, strings


def _used_names(item):
    """(The names, the string constants) the test function and its fixtures use, and the
    functions and classes of the test's module they name (their methods), all the way down."""
    functions = [getattr(item, 'function', None)] + [
        definition.func for definitions in item._fixtureinfo.name2fixturedefs.values()
        for definition in definitions]
    module = getattr(item.module, '__dict__', {}) if hasattr(item, 'module') else {}
    names, strings, seen = set(), set(), set()
    while functions:
        function = functions.pop()
        code = getattr(function, '__code__', None)
        if code is None or code in seen:
            continue
        seen.add(code)
        more = _names(code)
        names |= more[0]
        strings |= more[1]
        for name in more[0]:                 # the test module's own helpers it calls
            found = module.get(name)
            if getattr(found, '__module__', None) != getattr(item.module, '__name__', ''):
                continue
            if isinstance(found, type):
                functions += [f for f in vars(found).values() if hasattr(f, '__code__')]
            elif hasattr(found, '__code__'):
                functions.append(found)
    return names, strings


def live_reason(item):
    """Why `item` needs the realtime marker ('' if nothing says so)."""
    fixtures = sorted(LIVE_FIXTURES.intersection(item.fixturenames))
    if fixtures:
        return f'it uses the live fixture {fixtures[0]!r}'
    names, strings = _used_names(item)
    found = sorted(LIVE_NAMES & names)
    if found:
        return f'it uses {found[0]}'
    if {'demo', '--duration'} <= strings and (names & {'run_planter', 'DEMO'}
                                              or 'planter_ros.cli' in strings):
        return "it runs `planter demo --duration ...`"
    return ''


def live_where(item):
    """APART when a real-time test's live part runs in processes of its own (a demo run, the
    simulated drives' process), whose command process and simulated drives run SCHED_FIFO as
    on the machine; else HERE: its nodes, simulated drives or loops run in the test process
    itself (a command loop at the command process's priority while it runs,
    drive_helpers.as_the_command_process; the rest without real-time priority). A test marked
    by hand, whose live part nothing here names, counts as HERE, unless it says
    `pytest.mark.realtime(apart=True)`."""
    if item.get_closest_marker(REALTIME).kwargs.get('apart'):
        return APART
    if LIVE_FIXTURES.intersection(item.fixturenames):
        return HERE
    names, strings = _used_names(item)
    if LIVE_HERE_NAMES & names:
        return HERE
    demo = {'demo', '--duration'} <= strings and (names & {'run_planter', 'DEMO'}
                                                  or 'planter_ros.cli' in strings)
    return APART if demo or names & (LIVE_NAMES - LIVE_HERE_NAMES) else HERE


def _ids_file(config):
    """A file every process of this session sees (the session's base temporary directory)."""
    base = config._tmp_path_factory.getbasetemp()       # the session's (the worker's)
    root = base.parent if base.name.startswith('popen-gw') else base
    return root


def _realtime_ids_file(config):
    """{'kinds': {nodeid: HERE or APART}, 'alone': [the nodeids of `_alone` tests]} of the
    session's real-time tests."""
    return _ids_file(config) / 'realtime-tests.json'


def _alone(item):
    """Whether a real-time test can run on another process than its module's other real-time
    tests: it uses no fixture of its module made once for several tests."""
    module = _module(item.nodeid)
    return not any(definition.scope != 'function' and definition.baseid == module
                   for definitions in item._fixtureinfo.name2fixturedefs.values()
                   for definition in definitions)


def _done_dir(config):
    """One empty file per APART test done (what a HERE test waits for), named by a hash of
    its id."""
    return _ids_file(config) / 'realtime-tests-done'


def _count_done(config):
    try:
        return sum(1 for _ in _done_dir(config).iterdir())
    except FileNotFoundError:
        return 0


TURN_TIMEOUT = 1800.0       # s a test waits for its turn at most (a lost worker: go on)


def _wait_for_turn(item):
    """A HERE test waits until every APART test is done: it runs beside no demo-like test,
    only beside at most two other HERE tests (the other lanes) and the other tests at the
    background priority."""
    where = _realtime_kinds(item.config)
    if where.get(item.nodeid) != HERE:
        return
    total = sum(1 for kind in where.values() if kind == APART)
    deadline = time.monotonic() + TURN_TIMEOUT
    while _count_done(item.config) < total and time.monotonic() < deadline:
        time.sleep(0.1)


def _realtime_kinds(config):
    """{nodeid: HERE or APART} of the session's real-time tests ({} outside xdist)."""
    if not hasattr(config, 'workerinput'):
        return {}
    cached = config.stash.get(_KINDS, None)
    if cached is None:
        cached = json.loads(_realtime_ids_file(config).read_text())['kinds']
        config.stash[_KINDS] = cached
    return cached


def _number(node):
    """gw3 -> 3: the processes in the order xdist numbers them."""
    name = node.gateway.id
    return (int(name[2:]) if name[2:].isdigit() else 0, name)


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """Whole modules as units of work (their module fixtures made once); a module's tests
    marked realtime units of their own, each test alone unless it uses a fixture of its module
    made once (`_alone`), those live HERE apart from those live APART (xdist's own --dist
    loadgroup cannot group with this pytest). Two real-time lanes: both take the APART units
    first (two demo runs at once: their real-time processes run SCHED_FIFO); then the HERE
    units (each in its own process, after every APART one), which the third process (of four
    or more) takes too once every APART unit is under way (before that it runs other units);
    then any other unit. A worker waits at a test's set-up for what must end first
    (`_wait_for_turn`: xdist holds a worker's last test until more work comes, so the
    scheduler itself cannot make a lane wait). A process is given its next
    unit only when the last test of the one before is running, so that no unit waits on a busy
    process while another is idle. The other processes never run a real-time test. The
    controller collects nothing itself: the workers write the realtime tests' ids at
    collection (pytest_collection_modifyitems), before it schedules."""
    # lazy: a pytest hook of xdist's, called only when xdist runs the session
    from xdist.scheduler import LoadScopeScheduling

    class RealtimeLanes(LoadScopeScheduling):
        _where = None

        def _split_scope(self, nodeid):
            if self._where is None:
                written = json.loads(_realtime_ids_file(config).read_text())
                self._where, self._alone = written['kinds'], set(written['alone'])
            module = _module(nodeid)
            where = self._where.get(nodeid)
            unit = nodeid if nodeid in self._alone else module
            return f'{REALTIME} {where} {unit}' if where else module

        def _reschedule(self, node):
            """One unit at a time, the next given when the last test of the one before is
            running (xdist holds a worker's last test until more work or the shutdown comes):
            a unit queued on a busy process is one an idle process cannot take."""
            if node.shutting_down:
                return
            if not self.workqueue:
                node.shutdown()
                return
            if self._pending_of(self.assigned_work[node]) > 1:
                return
            self._assign_work_unit(node)

        def _assign_work_unit(self, node):
            nodes = sorted(self.nodes, key=_number)
            lanes = nodes[:2]
            third = nodes[2] if len(nodes) > 3 else None       # a HERE lane, the rest after
            here, apart, others = [], [], []
            for scope in self.workqueue:
                kind = scope.split(' ', 2)[:2]
                (here if kind == [REALTIME, HERE] else apart if kind == [REALTIME, APART]
                 else others).append(scope)
            if node in lanes:
                eligible = apart or here or others
            elif node is third:         # HERE once every APART unit is under way
                eligible = (here if here and not apart else others) or here
            else:
                eligible = others
            if not eligible:                         # only real-time units left, none for it
                if not node.shutting_down:
                    node.shutdown()
                return
            scope = eligible[0]
            work_unit = self.workqueue.pop(scope)
            self.assigned_work.setdefault(node, {})[scope] = work_unit
            collection = self.registered_collections[node]
            node.send_runtest_some([collection.index(nodeid)
                                    for nodeid, done in work_unit.items() if not done])
    return RealtimeLanes(config, log)


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """The real-time tests first (the real-time lanes take them first), those marked `slow`
    first among them (most are units of their own: the longest first, so that the lanes end
    together); then the modules with a test marked `slow`, for the same reason. Orders kept
    otherwise. A test that needs the realtime marker and lacks it is noted (it fails at its
    set-up)."""
    slow = {_module(item.nodeid) for item in items if item.get_closest_marker('slow')}

    def order(item):
        realtime = _realtime(item)
        return (not realtime, realtime and item.get_closest_marker('slow') is None,
                _module(item.nodeid) not in slow)
    items[:] = sorted(items, key=order)
    for item in items:
        if item.get_closest_marker('flaky'):
            item.stash[_UNMARKED] = ('flaky: a re-run that hides its first failure (pytest-'
                                     'rerunfailures, installed with colcon) is not allowed here')
        elif not _realtime(item):
            reason = live_reason(item)
            if reason:
                item.stash[_UNMARKED] = f'must be marked realtime ({reason}): add ' \
                    '`pytestmark = pytest.mark.realtime` to its module or ' \
                    '`@pytest.mark.realtime` to the test (test/conftest.py)'


@pytest.hookimpl(tryfirst=True)
def pytest_collection_finish(session):
    """(An xdist worker, before it reports its collection to the scheduler:) the real-time
    tests that will run, after any deselection (`-k`, `-m`): a test that waits for the APART
    ones to end waits for those only."""
    config = session.config
    if not hasattr(config, 'workerinput'):
        return
    realtime = {item.nodeid: live_where(item) for item in session.items if _realtime(item)}
    alone = [item.nodeid for item in session.items if _realtime(item) and _alone(item)]
    path = _realtime_ids_file(config)
    part = path.with_name(f'{path.name}.{os.getpid()}')
    part.write_text(json.dumps({'kinds': realtime, 'alone': alone}))
    os.replace(part, path)


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    """The CPU priority of this process for the test: the real-time tests at the priority the
    session started with, the other tests BACKGROUND_NICE lower (so they never starve the
    real-time tests' 10 ms loops and 0.2 s watchdogs). A lane runs its real-time tests first,
    so its priority only ever goes down. Never above the start's; without the right to change
    it (not root), what can be set is set."""
    refused = item.stash.get(_UNMARKED, '')
    if refused:
        pytest.fail(f'{item.nodeid} {refused}', pytrace=False)
    _wait_for_turn(item)
    if _realtime(item):
        # as the product's real-time processes do after start-up (command/process.py,
        # demo/sync_process.py): what the session made so far out of the collector's reach,
        # so a collection during the test (its loops, its simulated drives) is short. Without
        # it, the ~300 000 objects of a session's real-time process cost 150-240 ms per full
        # collection, a stop of every thread the loops under test never see in the product.
        gc.freeze()
    _set_nice(START_NICE if _realtime(item) else min(START_NICE + BACKGROUND_NICE, 19))


def _set_nice(wanted):
    """This process at nice `wanted`, never below (before) the session's start."""
    wanted = max(wanted, START_NICE)
    if os.getpriority(os.PRIO_PROCESS, 0) != wanted:
        try:
            os.setpriority(os.PRIO_PROCESS, 0, wanted)
        except PermissionError:
            pass                      # lowered before, not allowed back up: stays lower


def pytest_runtest_teardown(item, nextitem):
    if _realtime(item):
        gc.unfreeze()                    # collectable again, between the tests
        if _realtime_kinds(item.config).get(item.nodeid) == APART:
            done = _done_dir(item.config)
            done.mkdir(exist_ok=True)
            (done / hashlib.sha256(item.nodeid.encode()).hexdigest()[:16]).touch()


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_protocol(item, nextitem):
    """A real-time test that failed while the host itself stopped scheduling processes for more
    than host_stalls.STARVED s (its watcher process saw it) runs once more. Its reports then
    carry the first run's failure and the stall: `host_stall_rerun` (terminal summary) and the
    JUnit properties `host_stall_rerun` and `first_failure`. A stall inside the test process (a
    lock, the GIL, DDS) is no reason: the failure stands."""
    if not _realtime(item):
        return None
    from _pytest.runner import runtestprotocol
    watcher = host_stalls.watcher()
    item.ihook.pytest_runtest_logstart(nodeid=item.nodeid, location=item.location)
    start = time.monotonic()
    reports = runtestprotocol(item, nextitem=nextitem, log=False)
    if any(report.failed for report in reports):
        host_stalls.wait_for_reports()
        stall = watcher.longest(start, time.monotonic())
        if stall > host_stalls.STARVED:
            first = next(report for report in reports if report.failed)
            reason = (f'the host left every process unscheduled for {stall * 1000:.0f} ms '
                      f'during its first run, which failed ({_failure_line(reports)}): '
                      'run once more')
            item._initrequest()
            reports = runtestprotocol(item, nextitem=nextitem, log=False)
            for report in reports:
                report.host_stall_rerun = reason
                report.user_properties += [('host_stall_rerun', reason),
                                           ('first_failure', first.longreprtext)]
                report.sections.append(('first run (failed during a host stall)',
                                        first.longreprtext))
    for report in reports:
        item.ihook.pytest_runtest_logreport(report=report)
    item.ihook.pytest_runtest_logfinish(nodeid=item.nodeid, location=item.location)
    return True


def _failure_line(reports):
    report = next(report for report in reports if report.failed)
    crash = getattr(report.longrepr, 'reprcrash', None)
    first = crash.message.splitlines()[:1] if crash else []
    return f'{report.when}: {first[0]}' if first else report.when


_RERUNS = {}           # nodeid -> (why, the second run's outcome), in the reporting process


def pytest_configure(config):
    """pytest-rerunfailures comes with colcon: its silent re-runs are refused. Under xdist, the
    controller writes pytest's cache of the rewritten test modules first
    (`_cache_rewritten_tests`)."""
    if getattr(config.option, 'reruns', 0):
        raise pytest.UsageError('--reruns re-runs a failed test and hides its first failure: '
                                'this suite re-runs only what it shows (test/conftest.py)')
    if not hasattr(config, 'workerinput') and getattr(config.option, 'numprocesses', None):
        _cache_rewritten_tests(config)


def _cache_rewritten_tests(config):
    """Every xdist worker collects every test module, and pytest rewrites each module's asserts
    as it imports it: ~6 s of CPU per worker (a collection 9.4 s of CPU, 3.2 s with the cache).
    pytest caches the rewritten code next to the module (`__pycache__/*-pytest-*.pyc`, checked
    against the source's hash), but not where PYTHONDONTWRITEBYTECODE is set (CI, this
    workplace). So the controller writes that cache once before the workers start, as pytest
    itself would (the same functions, the same files); modules with a cache up to date are
    skipped. pytest's own helpers are internal: if they change, nothing is cached (slower,
    never wrong)."""
    try:
        from _pytest.assertion.rewrite import (
            PYC_TAIL, _read_pyc, _rewrite_test, _write_pyc, assertstate_key, get_cache_dir)
        state = config.stash[assertstate_key]
    except (ImportError, KeyError):
        return
    here = Path(__file__).parent
    patterns = config.getini('python_files')       # the modules pytest collects (and rewrites)
    modules = [path for path in here.glob('*.py')
               if path.name == 'conftest.py' or any(fnmatch(path.name, p) for p in patterns)]
    for path in sorted(modules):
        cache = get_cache_dir(path)
        pyc = cache / (path.name[:-3] + PYC_TAIL)
        try:
            if _read_pyc(path, pyc, state.trace) is not None:
                continue
            cache.mkdir(exist_ok=True)
            source_hash, code = _rewrite_test(path, config)
            _write_pyc(state, code, source_hash, pyc)
        except (TypeError, AttributeError, ValueError):   # pytest's internals changed
            return


def pytest_runtest_logreport(report):
    """(In the process that reports: the controller under xdist.) Note each re-run test."""
    reason = getattr(report, 'host_stall_rerun', None)
    if reason and report.when == 'call':
        _RERUNS[report.nodeid] = (reason, report.outcome)


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    reruns = _RERUNS
    if not reruns:
        return
    terminalreporter.section('real-time tests run twice after a host stall', sep='=',
                             red=True, bold=True)
    for nodeid, (reason, outcome) in reruns.items():
        terminalreporter.line(f'{nodeid}: {reason}; the second run {outcome}')
    if len(reruns) > 1:
        terminalreporter.line(f'{len(reruns)} tests needed a second run (at most one may): '
                              'the session fails', red=True, bold=True)


@pytest.hookimpl(tryfirst=True)
def pytest_sessionfinish(session, exitstatus):
    host_stalls.close()
    if len(_RERUNS) > 1 and session.exitstatus == pytest.ExitCode.OK:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
