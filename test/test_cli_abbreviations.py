"""No command takes an abbreviated option: `--dur 5` for `--duration 5` works only until an
option sharing the prefix is added, and then a user's script breaks silently. Every option of
every sub-command, abbreviated to its shortest unambiguous prefix, is refused (exit 2, one line
naming it), with the command's required arguments given so nothing else is wrong."""
import contextlib
import io
import subprocess
import sys

import pytest

from cli_helpers import REPO, run_planter

from planter_ros.cli.main import COMMANDS, BadInput, build_parser, main

SAMPLE = str(REPO / 'bags' / 'sample_tomato.mcap')
RICE = str(REPO / 'config' / 'rice_three_arm.yaml')
# the arguments each command needs before anything else may be wrong
REQUIRED = {
    ('design', 'five-bar'): ['--depth', '0.045', '--spacing', '0.2'],
    ('design', 'three-arm'): ['--params', RICE],
    ('optimize', 'three-arm'): [],
    ('bench',): [],
    ('demo',): [],
    ('replay',): [SAMPLE],
    ('analyze',): [SAMPLE, '--out', 'season'],
    ('simulate',): ['season', '--bags', '1'],
    ('cam', 'five-bar'): ['--depth', '0.045', '--design-spacing', '0.2', '--spacing', '0.2',
                          '--speed', '0.3'],
    ('commission',): ['--machine', str(REPO / 'config' / 'machines' / 'tomato_4row_tractor.yaml')],
    ('drive', 'check'): ['--machine',
                         str(REPO / 'config' / 'machines' / 'tomato_4row_tractor.yaml')],
}


def test_every_command_is_listed_here():
    assert sorted(REQUIRED) == sorted(COMMANDS)


def options_of(words):
    """{long option: takes a value} of the sub-command `words`."""
    parser = build_parser(list(words))
    for word in words:
        action = next(a for a in parser._actions if a.choices and word in a.choices)
        parser = action.choices[word]
    return {s: a.nargs != 0 for a in parser._actions for s in a.option_strings
            if s.startswith('--') and s != '--help'}


def shortest_prefix(option, options):
    """The shortest prefix of `option` (2 characters after '--' at least) that no other option
    starts with: what argparse took as that option when abbreviations were allowed."""
    for n in range(4, len(option)):
        prefix = option[:n]
        if not any(o != option and o.startswith(prefix) for o in options):
            return prefix
    return None


def abbreviations():
    for words in sorted(COMMANDS):
        options = options_of(words)
        for option, takes_value in sorted(options.items()):
            prefix = shortest_prefix(option, options)
            if prefix is not None:
                yield pytest.param(words, option, prefix, takes_value,
                                   id=f'{" ".join(words)} {prefix}')


@pytest.mark.parametrize('words, option, prefix, takes_value', list(abbreviations()))
def test_an_abbreviated_option_is_refused(words, option, prefix, takes_value):
    argv = [*words, *REQUIRED[words], prefix] + (['1'] if takes_value else [])
    with pytest.raises(BadInput) as refused:
        build_parser(argv).parse_args(argv)
    message = str(refused.value)
    assert 'unrecognized arguments' in message and prefix in message
    stderr = io.StringIO()
    with contextlib.redirect_stderr(stderr):
        assert main(argv) == 2
    assert len(stderr.getvalue().splitlines()) == 1


def test_every_command_has_options_to_abbreviate():
    """The test above covers every command (no command left out for want of options)."""
    assert {p.values[0] for p in abbreviations()} == set(COMMANDS)


def test_the_full_option_still_works_and_the_command_line_says_exit_2():
    assert run_planter('design', 'five-bar', '--depth', '0.045', '--spacing', '0.2',
                       '--json').returncode == 0
    out = run_planter('design', 'five-bar', '--dep', '0.045', '--spacing', '0.2')
    assert out.returncode == 2 and out.stderr.count('\n') == 1 and '--dep' in out.stderr


def test_the_sample_bag_generator_takes_no_abbreviation():
    out = subprocess.run([sys.executable, '-m', 'planter_ros.demo.samples', '--ou', 'x'],
                         capture_output=True, text=True, cwd=REPO, timeout=120)
    assert out.returncode == 2 and 'unrecognized arguments: --ou' in out.stderr
