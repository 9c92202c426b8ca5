"""The README's first screen promises two commands; the executables they name must exist in the
venv the bootstrap made (a fresh clone once got them in .venv/lib/planter_ros instead)."""
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def readme_commands():
    text = (REPO / 'README.md').read_text()
    block = re.search(r'```bash\n(.*?)```', text, re.S).group(1)
    return [line for line in block.splitlines() if line.strip() and not line.startswith('#')]


def test_readme_gives_exactly_two_commands_both_through_the_bootstrap():
    commands = readme_commands()
    assert len(commands) == 2
    assert all(c.startswith('./scripts/bootstrap.sh && ') for c in commands)
    assert 'pytest' in commands[1] and 'demo' in commands[0]


def test_the_executables_the_readme_runs_exist_in_this_venv():
    for command in readme_commands():
        exe = command.split(' && ')[1].split()[0]          # e.g. .venv/bin/planter
        name = Path(exe).name
        installed = Path(sys.prefix) / 'bin' / name
        assert installed.is_file(), f'{exe} is not installed in {sys.prefix}/bin'
    out = subprocess.run([str(Path(sys.prefix) / 'bin' / 'planter'), 'demo', '--help'],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and '--duration' in out.stdout
