"""The start-up plan made from a drive's EDS (drive/plan.py), pure: no bus.

The fixtures test/eds/*.eds are EDS files of our own, each modelling the properties seen in a
real drive's dictionary (not a vendor's file): EPOS4-like (no 607Eh, no RPDO event timer),
Everest-like (1005h const, 60C2h:2 read-only, no 6007h), Yiyou-like (no 1006h, 1016h, 603Fh,
607Ch; TPDOs without inhibit time or event timer), iPOS-like (603Fh not mappable), EPOS2-like
(no cyclic synchronous position, no event timers), IDM/ISCM-like (RPDO1 and TPDO1 take one
entry) and PRL-like (607Ah not mappable). The same plan is made from the file before the
start (the machine file's check) and at it."""
from __future__ import annotations

import dataclasses
from pathlib import Path
import re

import pytest

from cli_helpers import REPO, run_planter
from planter_ros.drive import objects as od
from planter_ros.drive.config import BusConfig, DriveConfig
from planter_ros.drive.dictionary import read_dictionary
from planter_ros.drive.eds import default_eds_path
from planter_ros.drive.errors import DictionaryError, DriveConfigError
from planter_ros.drive.plan import interpolation_period, plan_drive, plan_for_file
from planter_ros.drive.setup import DriveSetup
from planter_ros.drive.states import CYCLIC_SYNC_POSITION, PROFILE_VELOCITY

EDS = REPO / 'test' / 'eds'
PROFILES = sorted(p.stem for p in EDS.glob('*.eds'))
CONFIG = DriveConfig(drive_node_id=3, motor_gear_ratio=20.0, counts_per_motor_rev=131072)
ROW = DriveSetup(modes=('csp', 'pv'), homing_method=34)


def plan(name: str, setup: DriveSetup = ROW, config: DriveConfig = CONFIG):
    return plan_for_file(str(EDS / f'{name}.eds'), config, setup, 'row a, drive node 3')


def writes(p) -> dict[tuple[int, int], int]:
    return {(w.obj.index, w.obj.subindex): w.value for w in (*p.writes, *p.homing, *p.comm)}


def test_there_are_the_seven_profiles():
    assert PROFILES == ['epos2_like', 'epos4_like', 'everest_like', 'idm_like', 'ipos_like',
                        'prl_like', 'yiyou_like']


def test_each_profile_plans_its_row_or_is_refused_naming_the_object():
    refused = {}
    for name in PROFILES:
        try:
            p = plan(name)
        except DictionaryError as exc:
            refused[name] = str(exc)
            continue
        assert p.mode == CYCLIC_SYNC_POSITION
        assert '\n' not in '\n'.join(p.lines()).replace('\n', '')
    assert refused == {
        'epos2_like': "row a, drive node 3: 0x6502 supported drive modes 0x0000006D in this "
                      "drive's EDS lack csp: the machine file lists them for the row; list only "
                      "what the drive offers, or use a drive that has them",
        'prl_like': "row a, drive node 3: 0x607A target position is not PDO-mappable in this "
                    "drive's EDS: cyclic synchronous position needs it; use `modes: [pv]` or a "
                    "drive that maps it"}
    # what they refuse for CSP they run in profile velocity
    for name in refused:
        assert plan(name, dataclasses.replace(ROW, modes=('pv',))).mode == PROFILE_VELOCITY


def test_optional_writes_are_skipped_where_the_eds_lacks_them_or_holds_them_fixed():
    epos4 = plan('epos4_like')
    assert (0x607E, 0) not in writes(epos4)            # no polarity object: normal needs none
    assert (0x1400, 5) not in writes(epos4) and not epos4.deadline
    everest = plan('everest_like')
    assert (0x1005, 0) not in writes(everest)          # const 80h serves
    assert (0x60C2, 2) not in writes(everest) and writes(everest)[(0x60C2, 1)] == 10
    assert (0x6007, 0) not in writes(everest)
    yiyou = plan('yiyou_like')
    for absent in ((0x1006, 0), (0x1016, 1), (0x607C, 0), (0x1800, 3), (0x1800, 5)):
        assert absent not in writes(yiyou)
    assert not yiyou.heartbeat_consumer
    assert any('will not stop by itself if the master dies' in w for w in yiyou.warnings)
    assert od.ERROR_CODE not in yiyou.tpdos[0].entries
    ipos = plan('ipos_like')
    assert ipos.tpdos[0].entries == (od.STATUSWORD,)   # 603Fh not mappable: EMCY instead
    # the project's own EDS: everything written, the default layouts
    own = plan_for_file(str(default_eds_path()), CONFIG, ROW)
    assert [pdo.entries for pdo in own.rpdos] == [od.RPDO_POSITION.entries]
    assert [pdo.entries for pdo in own.tpdos] == [layout.entries for layout in od.TPDOS]
    assert {(0x1400, 5), (0x1016, 1), (0x6007, 0), (0x607E, 0), (0x1005, 0)} <= set(
        writes(own))


def test_layouts_spread_over_more_pdos_where_a_pdo_takes_one_entry():
    idm = plan('idm_like')
    assert [(p.number, p.entries) for p in idm.rpdos] == [
        (1, (od.CONTROLWORD,)), (2, (od.TARGET_POSITION,))]
    assert [(p.number, p.entries) for p in idm.tpdos] == [
        (1, (od.STATUSWORD,)), (2, (od.ERROR_CODE,)),
        (3, (od.POSITION_ACTUAL, od.VELOCITY_ACTUAL))]
    # every PDO is written in CiA 301's order: invalid, type, count 0, entries, count, valid
    rpdo2 = [(w.obj.index, w.obj.subindex, w.value) for w in idm.comm
             if w.obj.index in (0x1401, 0x1601)]
    assert rpdo2 == [(0x1401, 1, 0x80000303), (0x1401, 2, 1), (0x1601, 0, 0),
                     (0x1601, 1, 0x607A0020), (0x1601, 0, 1), (0x1401, 1, 0x303)]


def test_a_tpdo_without_event_timer_reports_on_sync_in_profile_velocity():
    epos2 = plan('epos2_like', dataclasses.replace(ROW, modes=('pv',)))
    assert epos2.sync_feedback and epos2.needs_sync
    assert {p.trans_type for p in epos2.tpdos} == {1} and epos2.rpdos[0].trans_type == 255
    epos4 = plan('epos4_like', dataclasses.replace(ROW, modes=('pv',)))
    assert not epos4.needs_sync and {p.event_timer for p in epos4.tpdos} == {10}


def test_60c2_states_exactly_the_period_1006_states_for_every_period_allowed():
    allowed = 0
    for micro in range(2000, 100_001):
        period = micro / 1e6
        try:
            BusConfig(sync_period=period)
        except DriveConfigError:
            continue
        allowed += 1
        value, index = interpolation_period(period)
        assert 1 <= value <= 255
        # exact: value × 10^index s == 1006h µs, in integers
        assert value * 10 ** (index + 6) == micro if index >= -6 else False
    # 2.00..2.55 ms by 10 µs, 2.6..25.5 ms by 0.1 ms, 26..100 ms by 1 ms
    assert allowed == 56 + 230 + 75
    for period, want in ((0.0025, (25, -4)), (0.0035, (35, -4)), (0.0125, (125, -4)),
                         (0.01, (10, -3))):
        assert interpolation_period(period) == want


def test_a_fixed_interpolation_index_refuses_a_period_it_cannot_state():
    config = dataclasses.replace(CONFIG, sync_period=0.0025)
    with pytest.raises(DictionaryError) as err:
        plan('everest_like', config=config)
    assert str(err.value) == (
        "row a, drive node 3: 0x60C2:2 interpolation time index is fixed at -3 in this drive's "
        "EDS: sync_period 0.0025 s is no whole number of 10^-3 s up to 255; use a sync_period "
        "that is one (whole ms for -3)")
    assert plan('epos4_like', config=config).interpolation == (25, -4)


@pytest.fixture
def eds_variant(tmp_path):
    """variant(drop=[sections], change={section: (key, value)}) -> a copy of our EDS."""
    text = default_eds_path().read_text()

    def variant(drop=(), change=None, name='variant.eds'):
        out = text
        for section in drop:
            out = re.sub(rf'\[{section}\][^\[]*', '', out)
        for section, (key, value) in (change or {}).items():
            block = re.search(rf'\[{section}\][^\[]*', out).group(0)
            out = out.replace(block, re.sub(rf'{key}=[^\n]*', f'{key}={value}', block))
        path = tmp_path / name
        path.write_text(out)
        return path
    return variant


def test_each_refusal_names_the_object_what_it_is_for_and_what_to_do(eds_variant):
    cases = [
        (dict(drop=['60FF']), dataclasses.replace(ROW, modes=('pv',)),
         "0x60FF target velocity is not in this drive's EDS: profile velocity needs it; use "
         "`modes: [csp]` or a drive that maps it"),
        (dict(drop=['1017']), ROW,
         "0x1017 producer heartbeat time is not in this drive's EDS: the master watches the "
         "drive's heartbeat (a drive lost stops its row); set drive_heartbeat_period to the "
         "drive's own, or use a drive that produces a heartbeat"),
        (dict(drop=['607E']), dataclasses.replace(ROW, polarity='reversed'),
         "0x607E polarity is not in this drive's EDS: the machine file's `polarity: reversed` "
         "needs it; reverse the direction in the drive's own configuration and write "
         "`polarity: normal`"),
        (dict(change={'6064': ('DataType', '0x0007')}), ROW,
         "0x6064 position actual value is UNSIGNED32 in this drive's EDS: the master reads and "
         "writes it as INTEGER32; correct the EDS (the drive maker's is right)"),
        (dict(change={'6041': ('PDOMapping', '0')}), ROW,
         "0x6041 statusword is not PDO-mappable in this drive's EDS: the drive's state and "
         "faults travel in it; use a CiA 402 drive that maps it"),
        (dict(drop=['6098']), ROW,
         "0x6098 homing method is not in this drive's EDS: homing at start needs it; use "
         "homing_method 0 (none) or a drive that homes"),
    ]
    for variant, setup, reason in cases:
        with pytest.raises(DictionaryError) as err:
            plan_for_file(str(eds_variant(**variant)), CONFIG, setup, 'row a, drive node 3')
        assert str(err.value) == f'row a, drive node 3: {reason}'


def test_a_file_that_is_no_eds_is_one_clean_refusal(tmp_path):
    binary = tmp_path / 'drive.eds'
    binary.write_bytes(bytes(range(256)) * 40)
    text = tmp_path / 'words.eds'
    text.write_text('this is not an EDS\n')
    suffix = tmp_path / 'drive.txt'
    suffix.write_text(default_eds_path().read_text())
    for path, why in ((binary, 'is not a text file'), (text, 'is not an EDS canopen can read'),
                      (suffix, 'is not an EDS or DCF file name'),
                      (tmp_path / 'missing.eds', 'is not a file')):
        with pytest.raises(DictionaryError) as err:
            read_dictionary(path, 1)
        assert why in str(err.value) and '\n' not in str(err.value)


def test_the_plan_is_the_same_whether_from_the_file_or_at_start():
    """One plan, two uses: the check's (`plan_for_file`, the machine file's modes) and the
    start's (plan_drive on the dictionary the master loads, the mode from the drive's 6502h)."""
    for name in ('epos4_like', 'idm_like', 'yiyou_like'):
        dictionary = read_dictionary(EDS / f'{name}.eds', CONFIG.drive_node_id)
        at_start = plan_drive(dictionary, CONFIG, ROW, CYCLIC_SYNC_POSITION)
        assert plan(name) == at_start


def machine_with(tmp_path, eds: Path, name='machine.yaml', **row):
    text = (REPO / 'config' / 'machines' / 'tomato_4row_tractor.yaml').read_text()
    block = '    modes: [csp, pv]\n'
    extra = ''.join(f'    {key}: {value}\n' for key, value in row.items())
    text = text.replace(block, block + f'    eds: {eds.name}\n' + extra, 1)
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_machine_file_whose_drive_cannot_run_its_row_is_refused_before_the_start(tmp_path):
    """`python -m planter_ros.scene.machine_file --check`: exit 2, one line (issue 32: an EDS
    with a wrong type, a binary EDS, a homing method no CiA 402 drive knows)."""
    import shutil
    cases = []
    prl = tmp_path / 'prl_like.eds'
    shutil.copy(EDS / 'prl_like.eds', prl)
    cases.append((machine_with(tmp_path, prl, 'prl.yaml'),
                  '0x607A target position is not PDO-mappable'))
    binary = tmp_path / 'binary.eds'
    binary.write_bytes(b'\x89PNG\r\n\x1a\n' + bytes(200))
    cases.append((machine_with(tmp_path, binary, 'binary.yaml'), 'is not a text file'))
    for method in (99, 127, 15):
        epos4 = tmp_path / 'epos4_like.eds'
        shutil.copy(EDS / 'epos4_like.eds', epos4)
        path = machine_with(tmp_path, epos4, f'homing_{method}.yaml')
        path.write_text(path.read_text().replace('homing_method: 34', f'homing_method: '
                                                 f'{method}', 1))
        cases.append((path, f'homing_method = {method} is out of range'))
    import subprocess
    import sys
    for path, want in cases:
        done = subprocess.run([sys.executable, '-m', 'planter_ros.scene.machine_file', str(path),
                               '--check'], capture_output=True, text=True, cwd=REPO,
                              timeout=60)
        assert done.returncode == 2, done.stderr
        assert want in done.stderr and len(done.stderr.strip().splitlines()) == 1, done.stderr
        assert 'Traceback' not in done.stderr


@pytest.mark.realtime
def test_a_cam_scene_on_rows_without_csp_is_refused_before_the_demo_starts(tmp_path):
    machine = (REPO / 'config' / 'machines' / 'tomato_4row_tractor.yaml').read_text()
    path = tmp_path / 'pv_only.yaml'
    path.write_text(machine.replace('modes: [csp, pv]', 'modes: [pv]'))
    scene = REPO / 'config' / 'tomato_cam.yaml'
    done = run_planter('demo', '--machine', path, '--scene', scene, '--duration', '8',
                       timeout=120)
    assert done.returncode == 2, done.stderr
    assert 'speed_profile cam needs cyclic synchronous position' in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
