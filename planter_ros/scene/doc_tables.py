"""The tables in doc/ that come from the code's one declaration: the topics (interfaces.TOPICS),
each node's parameters (scene.schema.node_specs, from the configuration classes) and the machine
file's keys (scene.machine_file). A page holds a generated table as the docs hold every generated
block, between a marker naming the command that prints it and an end marker:

    <!-- generated: python -m planter_ros.scene.doc_tables topics -->
    ...
    <!-- end generated -->

`python -m planter_ros.scene.doc_tables NAME` prints one table; without a name it rewrites
every such table in doc/ from the code. test/test_doc_tables.py fails when a page's table
differs from what the code declares.
"""

from dataclasses import MISSING
from pathlib import Path
import re
import sys

from planter_ros import interfaces
from planter_ros.config import Spec, specs
from planter_ros.rows import RowLayout, RowSettings
from planter_ros.scene.machine_file import field_table
from planter_ros.scene.schema import ROS_PARAMETERS, node_specs
from planter_ros.sensing.ground_speed_sources import GroundSpeedSourceConfig

__all__ = ['TABLES', 'render', 'update_page']

MARK = re.compile(r'(<!-- generated: python -m planter_ros\.scene\.doc_tables ([\w:-]+) -->\n)'
                  r'(.*?)(<!-- end generated -->)', re.S)


def _cell(text: object) -> str:
    return str(text).replace('|', '\\|').replace('\n', ' ')


def _default(spec: Spec) -> str:
    if spec.default is MISSING:
        return 'required'
    if spec.kind is bool:
        return 'true' if spec.default else 'false'
    if spec.kind is str:
        return f"`'{spec.default}'`" if spec.default else "`''`"
    return f'`{spec.default}`'


def topics_table() -> str:
    lines = ['| topic | type | QoS | what |', '|---|---|---|---|']
    for topic in interfaces.TOPICS:
        qos = topic.qos
        lines.append(f'| `{topic.resolved()}` | {topic.type_name} | {qos.reliability}, '
                     f'{qos.durability}, keep last {qos.depth} | {_cell(topic.doc)} |')
    return '\n'.join(lines)


def node_parameter_specs(node: str) -> dict:
    """{name: Spec} of the parameters `node` declares (rows aside): the three scene nodes'
    from the scene's schema, ground_speed_node's from its sources' settings."""
    if node == 'ground_speed_node':
        return {spec.name: spec for spec in specs(GroundSpeedSourceConfig)}
    return node_specs(node)


def services_table() -> str:
    lines = ['| service | type | what |', '|---|---|---|']
    for service in (interfaces.RESET_FAULT, interfaces.SECTION):
        lines.append(f'| `<row>/{service.name}` (`{service.name}` without rows) | '
                     f'{service.type_name} | {_cell(service.doc)} |')
    service = interfaces.ENABLE_ROWS
    lines.append(f'| `{service.name}` | {service.type_name} | {_cell(service.doc)} |')
    return '\n'.join(lines)


def rows_table() -> str:
    """The row parameters of a scene (`rows` and each row's block)."""
    lines = ['| parameter | allowed | default | read-only | what |', '|---|---|---|---|---|']
    for prefix, cls in (('', RowLayout), ('<row>.', RowSettings)):
        for spec in specs(cls):
            lines.append(f'| `{prefix}{spec.name}` | {_cell(spec.allowed())} | '
                         f'{_cell(_default(spec))} | {"yes" if spec.read_only else "no"} | '
                         f'{_cell(spec.description)} |')
    return '\n'.join(lines)


def parameters_table(node: str) -> str:
    lines = ['| parameter | allowed | default | read-only | what |', '|---|---|---|---|---|']
    for name, spec in node_parameter_specs(node).items():
        if name in ROS_PARAMETERS:
            continue
        lines.append(f'| `{name}` | {_cell(spec.allowed())} | {_cell(_default(spec))} | '
                     f'{"yes" if spec.read_only else "no"} | {_cell(spec.description)} |')
    if node in ('sync_node', 'monitor_node'):
        for spec in specs(RowSettings):
            lines.append(f'| `<row>.{spec.name}` | {_cell(spec.allowed())} | '
                         f'{_cell(_default(spec))} | {"yes" if spec.read_only else "no"} | '
                         f'{_cell(spec.description)} |')
    return '\n'.join(lines)


def machine_table() -> str:
    lines = ['| key | allowed | default | what |', '|---|---|---|---|']
    lines.append('| `machine` | text | `\'\'` | the machine\'s name, for people and recordings |')
    for key, spec in field_table():
        lines.append(f'| `{key}` | {_cell(spec.allowed())} | {_cell(_default(spec))} | '
                     f'{_cell(spec.description)} |')
    return '\n'.join(lines)


# table name in a page's marker -> its text
TABLES = {
    'topics': topics_table,
    'services': services_table,
    'rows': rows_table,
    'parameters:design_node': lambda: parameters_table('design_node'),
    'parameters:sync_node': lambda: parameters_table('sync_node'),
    'parameters:monitor_node': lambda: parameters_table('monitor_node'),
    'parameters:ground_speed_node': lambda: parameters_table('ground_speed_node'),
    'machine-file': machine_table,
}


def render(name: str) -> str:
    return TABLES[name]() + '\n'


def update_page(text: str) -> tuple[str, list[str]]:
    """`text` with every generated table rewritten, and the names of the tables found
    (KeyError for a marker naming no table)."""
    found = []

    def fill(match: re.Match) -> str:
        found.append(match.group(2))
        return match.group(1) + render(match.group(2)) + match.group(4)
    return MARK.sub(fill, text), found


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv:
        if argv[0] not in TABLES:
            print(f'doc_tables: error: {argv[0]!r} is not a table: allowed '
                  + ', '.join(TABLES), file=sys.stderr)
            return 2
        print(TABLES[argv[0]]())
        return 0
    doc = Path(__file__).resolve().parents[2] / 'doc'
    for page in sorted(doc.glob('*.md')):
        text = page.read_text()
        new, found = update_page(text)
        if new != text:
            page.write_text(new)
            print(f'{page.name}: rewrote {", ".join(found)}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
