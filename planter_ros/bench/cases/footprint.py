"""Footprint rows: start-up time, import time and peak memory (RSS) of a minimal five-bar run,
each in a fresh interpreter, next to a bare interpreter for scale; and which heavy modules the
run loaded (it should load none: a five-bar scene skips what it does not need)."""

from collections.abc import Iterator
import json
import os
import subprocess
import sys
import time

from ..registry import BenchContext, Row, bench_case
from ..timing import from_samples

# heavy modules a five-bar design must not load
HEAVY = ('scipy', 'matplotlib', 'rclpy', 'mpmath', 'planter_ros.kinematics.three_arm',
         'planter_ros.optimise', 'planter_ros.optimize')

# Peak RSS is read in the child from /proc/self/status (VmHWM, reset by exec): the parent's
# rusage would report the forked bench process's own memory.
PEAK_RSS = r'''
import atexit, sys
def _peak():
    with open('/proc/self/status') as f:
        kb = [l.split()[1] for l in f if l.startswith('VmHWM')][0]
    print('peak-rss-kb', kb, file=sys.stderr)
atexit.register(_peak)
'''

MINIMAL_RUN = r'''
import json, sys, time
t0 = time.perf_counter()
from planter_ros.kinematics.five_bar import design_five_bar
t1 = time.perf_counter()
d = design_five_bar(0.045, 0.2, 0.05)
t2 = time.perf_counter()
heavy = sorted(m for m in sys.modules if any(m == h or m.startswith(h + '.') for h in HEAVY))
print(json.dumps({'import_s': t1 - t0, 'design_s': t2 - t1, 'l1': d.l1, 'heavy': heavy,
                  'modules': len(sys.modules)}))
'''

CLI_RUN = r'''
sys.argv = ['planter', 'design', 'five-bar', '--depth', '0.045', '--spacing', '0.2']
from planter_ros.cli.main import main
sys.exit(main())
'''


def run_measured(code: str, env: dict[str, str] | None = None) -> tuple[float, int, str]:
    """Run `python -c code` in a fresh interpreter; (wall seconds, peak RSS bytes, stdout)."""
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, '-c', PEAK_RSS + code], capture_output=True,
                          text=True, env=env)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f'minimal run exited {proc.returncode}: {proc.stderr[-300:]}')
    peaks = [line.split()[1] for line in proc.stderr.splitlines()
             if line.startswith('peak-rss-kb ')]
    return wall, int(peaks[-1]) * 1024, proc.stdout


def _env() -> dict[str, str]:
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(
        os.path.abspath(__file__)))))
    path = os.environ.get('PYTHONPATH', '')
    return dict(os.environ, PYTHONPATH=root + (os.pathsep + path if path else ''))


@bench_case('footprint of a minimal five-bar run')
def footprint(ctx: BenchContext) -> Iterator[Row]:
    env = _env()
    repeats = ctx.n(7, 1)
    runs = {
        'bare interpreter (python -c pass)': 'pass',
        'import five_bar + one design': f'HEAVY = {HEAVY!r}\n' + MINIMAL_RUN,
        'planter design five-bar (CLI main)': CLI_RUN,
    }
    for method, code in runs.items():
        walls, rss, imports, heavy = [], [], [], None
        for _ in range(repeats):
            wall, peak, out = run_measured(code, env)
            walls.append(wall)
            rss.append(peak)
            if method.startswith('import'):
                r = json.loads(out)
                imports.append(r['import_s'])
                heavy = r['heavy']
        peak_mb = max(rss) / 1e6
        note = f'peak RSS {peak_mb:.1f} MB (max of {repeats})'
        extra: dict[str, object] = {'peak_rss_bytes': max(rss)}
        if imports:
            it = from_samples(imports)
            note += (f'; import five_bar {it.median * 1e3:.1f} ms '
                     f'(p10-p90 {it.p10 * 1e3:.1f}-{it.p90 * 1e3:.1f}); heavy modules loaded: '
                     f"{', '.join(heavy) if heavy else 'none'}")
            extra.update({'import_s': it.median, 'import_p10_s': it.p10,
                          'import_p90_s': it.p90, 'heavy_modules': heavy})
        yield Row('footprint (fresh process)', method, 1, 'run', from_samples(walls),
                  note=note, extra=extra)
