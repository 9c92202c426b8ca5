"""The topic, parameter and machine-file tables in doc/ are the code's (scene/doc_tables.py):
a page whose generated table differs from what the code declares fails here, naming the page;
`python -m planter_ros.scene.doc_tables` rewrites them."""
import pytest

from cli_helpers import REPO
from planter_ros import interfaces
from planter_ros.scene.doc_tables import TABLES, update_page

DOC = REPO / 'doc'
PAGES = sorted(DOC.glob('*.md'))


@pytest.mark.parametrize('page', PAGES, ids=lambda p: p.name)
def test_every_generated_table_says_what_the_code_declares(page):
    text = page.read_text()
    assert update_page(text)[0] == text, (
        f'doc/{page.name}: a generated table differs from the code; run '
        '`python -m planter_ros.scene.doc_tables`')


def test_every_table_is_on_a_page():
    found = set()
    for page in PAGES:
        found |= set(update_page(page.read_text())[1])
    assert found == set(TABLES)


def test_the_topic_table_lists_every_topic_gnss_fix_too():
    text = (DOC / 'node_graph.md').read_text()
    for topic in interfaces.TOPICS:
        assert f'| `{topic.resolved()}` | {topic.type_name} |' in text
    assert '| `/planter/gnss/fix` | sensor_msgs/msg/NavSatFix |' in text


def test_a_hand_edited_table_is_caught():
    text = (DOC / 'machine_file.md').read_text()
    edited = text.replace('integer 1..127', 'integer 1..255', 1)
    assert edited != text and update_page(edited)[0] != edited


def test_a_marker_naming_no_table_is_refused():
    with pytest.raises(KeyError):
        update_page('<!-- generated: python -m planter_ros.scene.doc_tables nothing -->\n'
                    '<!-- end generated -->')
