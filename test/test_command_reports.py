"""The command process's messages (command.reports): to_data() gives what dataclasses.asdict
gives, and from_data() of that data, through JSON, builds the message again."""
from dataclasses import asdict
import json

import pytest

from planter_ros.command.reports import (CommandExit, CommandReport, Ready, Recovery, Reply,
                                         ReportError, RowReport, RowSnapshot, Snapshot)


def _report() -> CommandReport:
    recovery = Recovery('drive fault 0x8611', True, False, 0.25, 1.5, 3, True, auto_resets=1)
    row = RowReport('left', 1, 'following error', '', {'gaps': 10, 'max': 0.012,
                                                       'over': {'5 ms': 2}},
                    plants_missed=3, restarts=1, recoveries=[recovery])
    return CommandReport(120, {'jump': 2}, 118, {}, 1, 0, True, False, [row, RowReport(
        'right', 0, '', 'no drive', {})], {'gaps': [1, 2]}, 0.1, csp=True,
        sync={'period': 0.01, 'nested': [{'a': [1, 2]}]})


MESSAGES = [
    _report(),
    Snapshot((RowSnapshot('left', 1.5, 1.49, 'OPERATION ENABLED', True),
              RowSnapshot('right', 0.0, 0.0, '-', False)), 0.25),
    Snapshot(),
    Ready(1234, 80, ('SCHED_FIFO refused',), 2, 'cyclic synchronous position'),
    Reply(True, 'row left on', True),
    CommandExit('SIGTERM', False),
]


@pytest.mark.parametrize('message', MESSAGES, ids=lambda m: type(m).__name__)
def test_to_data_is_what_asdict_gives_and_from_data_builds_the_message_again(message):
    data = message.to_data()
    assert data == asdict(message)
    assert type(data) is dict
    for name in data:                     # containers rebuilt as asdict rebuilds them
        assert type(data[name]) is type(asdict(message)[name])
    again = type(message).from_data(json.loads(json.dumps(data)))
    assert again == message


def test_to_data_copies_the_containers_it_is_given():
    report = _report()
    data = report.to_data()
    data['rows'][0]['loop']['over']['5 ms'] = 99
    data['rejected']['jump'] = 0
    assert report.rows[0].loop['over']['5 ms'] == 2
    assert report.rejected == {'jump': 2}


def test_from_data_names_a_missing_field_and_a_row_list_that_is_no_list():
    with pytest.raises(ReportError, match="RowSnapshot: no 'state'"):
        Snapshot.from_data({'rows': [{'label': 'a', 'command': 0.0, 'velocity': 0.0,
                                      'running': True}]})
    with pytest.raises(ReportError, match='RowSnapshot: expected a list, got int'):
        Snapshot.from_data({'rows': 3})
    with pytest.raises(ReportError, match='Snapshot: expected a mapping, got list'):
        Snapshot.from_data([])
