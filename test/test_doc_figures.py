"""Figures in doc/ do not drift from the code: a table the code generates is the output of its
command today (the block names the command), and a measured figure says when and with which
command it was measured."""
import re
import shlex
import subprocess
import sys

from cli_helpers import REPO

GENERATED = re.compile(r'<!-- generated: (.+?) -->\n(.*?)\n<!-- end generated -->', re.S)


def test_every_generated_block_is_its_commands_output_today():
    page = (REPO / 'doc' / 'node_graph.md').read_text()
    blocks = GENERATED.findall(page)
    assert blocks, 'doc/node_graph.md lost its generated blocks'
    for command, text in blocks:
        words = shlex.split(command)
        assert words[:2] == ['python', '-m'], command
        out = subprocess.run([sys.executable, *words[1:]], capture_output=True, text=True,
                             cwd=REPO, timeout=300)
        assert out.returncode == 0, out.stderr
        assert text == out.stdout.strip(), f'regenerate the block of `{command}`'


def test_every_measured_paragraph_is_dated_and_names_its_command():
    page = (REPO / 'doc' / 'node_graph.md').read_text()
    measured = [p for p in page.split('\n\n')
                if re.match(r'(\*\*[^*]+\*\* )?(Measured|Seen)\b', p)]
    assert len(measured) >= 3
    for paragraph in measured:
        assert re.search(r'\b20\d\d-\d\d-\d\d\b', paragraph), paragraph[:120]
        assert re.search(r'`(planter|python|pytest)[^`]*`', paragraph), paragraph[:120]
