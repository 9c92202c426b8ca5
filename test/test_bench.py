"""`planter bench` as CI runs it: the quick smoke run works, its JSON is complete and its
errors come from the mpmath reference (exact methods at round-off, the paper's formula not)."""
import json

from cli_helpers import run_planter


def test_quick_bench_runs_and_reports_every_row_with_time_and_error(tmp_path):
    plot = tmp_path / 'tradeoff.png'
    out = run_planter('bench', '--quick', '--json', '--plot', plot, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    report = json.loads(out.stdout)
    assert report['quick'] is True
    assert report['machine']['cpu'] and report['machine']['numpy']
    rows = report['rows']
    assert all(r['status'] in ('ok', 'not available') for r in rows)
    ok = [r for r in rows if r['status'] == 'ok']
    whats = {r['what'] for r in ok}
    assert {'five-bar reverse design', 'hole width', 'trajectory evaluation',
            'footprint (fresh process)'} <= whats
    for r in ok:
        assert r['median_s'] > 0 and r['p10_s'] <= r['median_s'] <= r['p90_s']
    design = [r for r in ok if r['what'] == 'five-bar reverse design']
    exact = [r for r in design if r['method'].startswith('exact')]
    paper = [r for r in design if r['method'].startswith('paper')]
    assert exact and paper
    assert all(r['error'] < 1e-12 for r in exact)          # round-off
    assert all(r['error'] > 1e-3 for r in paper)           # the ψ³/6 approximation shows
    sampling = [r for r in ok if r['method'].startswith('dense sampling')]
    assert len(sampling) >= 2 and sampling[0]['error'] > sampling[-1]['error']
    footprint = [r for r in ok if r['method'].startswith('import five_bar')][0]
    assert footprint['heavy_modules'] == [] and footprint['peak_rss_bytes'] > 0
    assert plot.stat().st_size > 10_000
    # the node-graph rows: latencies with their tail, replay speed and its error vs live
    sync = [r for r in ok if r['what'].startswith('sync loop')]
    assert sync and all(r['median_s'] <= r['p99_s'] and r['matched'] > 0 for r in sync)
    assert all(t['target'].startswith('p99 ≤ 2 ms') for r in sync for t in r['targets'])
    drive = [r for r in ok if r['what'].startswith('CAN drive')]
    assert {'SDO round trip (6041h upload)', 'RPDO latency, send_velocity() → drive decoded it'} \
        <= {r['method'] for r in drive}
    assert all(r['median_s'] <= r['p99_s'] and r['error'] is None for r in drive)
    replay = [r for r in ok if r['what'].startswith('replay')]
    generated = [r for r in replay if r['method'].startswith('generated')]
    recorded = [r for r in replay if 'live monitor' in r['method']]
    assert generated and generated[0]['error'] is None            # no live predictions in it
    assert generated[0]['times_real_time'] > 0 and generated[0]['targets']
    assert recorded and all(r['error'] < 1e-9 for r in recorded)  # replay reproduces the monitor


def test_bench_table_names_the_machine_and_targets():
    out = run_planter('bench', '--quick', '--only', 'reverse design', timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.startswith('planter bench · ') and 'numpy' in out.stdout
    assert '≤ 20 µs' in out.stdout and 'mpmath' in out.stdout
    assert 'bench: five-bar reverse design' in out.stderr      # progress goes to stderr


def test_bench_rejects_bad_options_in_one_line():
    out = run_planter('bench', '--only', 'no-such-case')
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1
    out = run_planter('bench', '--plot', 'x.jpg')
    assert out.returncode == 2 and 'png' in out.stderr
