"""`planter drive check`: the bring-up test of each row's drive, against simulated drives that
serve each profile's EDS (test/eds): the plan printed, enabled with SYNC, moved a few degrees,
disabled; a drive its row cannot run on refused before anything moves."""
from __future__ import annotations

import re
import shutil

import pytest

from cli_helpers import REPO, run_planter

EDS = REPO / 'test' / 'eds'
PROFILES = sorted(p.stem for p in EDS.glob('*.eds'))
PV_ONLY = ('epos2_like', 'prl_like')      # no CSP over PDOs: their rows run profile velocity

pytestmark = pytest.mark.realtime


def machine(tmp_path, modes=None):
    rows = []
    for node, name in enumerate(PROFILES, start=1):
        shutil.copy(EDS / f'{name}.eds', tmp_path / f'{name}.eds')
        row_modes = (modes or {}).get(name, '[pv]' if name in PV_ONLY else '[csp, pv]')
        rows.append(f'  {name}:\n    node_id: {node}\n    lateral_offset: {0.5 * node}\n'
                    '    longitudinal_offset: -2.0\n    gear_ratio: 20.0\n'
                    '    encoder_counts: 4096\n    max_motor_speed: 600.0\n'
                    '    max_motor_acceleration: 5000.0\n    max_torque: 5.0\n'
                    f'    modes: {row_modes}\n    eds: {name}.eds\n')
    path = tmp_path / 'machine.yaml'
    path.write_text('machine: bring-up\ncan:\n  interface: virtual\n  channel: vcan0\n'
                    '  bitrate: 500000\nrows:\n' + ''.join(rows))
    return path


def test_every_profile_passes_the_bring_up_and_prints_its_plan(tmp_path):
    done = run_planter('drive', 'check', '--machine', machine(tmp_path), timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    out = done.stdout
    blocks = re.split(r'^row ', out, flags=re.M)[1:]
    assert [block.split(' ', 1)[0] for block in blocks] == PROFILES
    for block in blocks:
        name = block.split(' ', 1)[0]
        mode = 'profile velocity' if name in PV_ONLY else 'cyclic synchronous position'
        assert f'plan: mode: {mode}' in block, block
        assert re.search(r'enabled in \d+ ms, [1-9]\d* SYNC sent while starting', block), block
        moved = float(re.search(r'([+-][\d.]+) deg reported', block).group(1))
        assert abs(moved - 5.0) < 0.5, block
        assert 'disabled: passed' in block
    idm = blocks[PROFILES.index('idm_like')]
    assert 'RPDO1: 6040h controlword;' in idm and 'RPDO2: 607Ah target position;' in idm
    yiyou = blocks[PROFILES.index('yiyou_like')]
    assert 'will not stop by itself if the master dies' in yiyou


def test_a_row_its_drive_cannot_run_is_refused_before_the_bus_is_touched(tmp_path):
    done = run_planter('drive', 'check', '--machine',
                       machine(tmp_path, {'prl_like': '[csp, pv]'}), timeout=120)
    assert done.returncode == 2 and done.stdout == ''
    line, = done.stderr.strip().splitlines()
    assert line.startswith('planter: error: drive check: machine file ')
    assert line.endswith("row prl_like, drive node 6: 0x607A target position is not "
                         "PDO-mappable in this drive's EDS: cyclic synchronous position needs "
                         "it; use `modes: [pv]` or a drive that maps it")
