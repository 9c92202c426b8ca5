"""The design is typed (planter_ros.design): built from a scene, to the topic's JSON and back in
one place, read by attributes everywhere else. A malformed or foreign `design` message is one
line naming what is wrong."""
import ast
import json
import math

import pytest

from planter_ros.design import (DesignMessageError, FiveBar, ThreeArm, design_for_scene,
                                from_dict, from_json, to_dict, to_json)
from planter_ros.scene import load_scene

from cli_helpers import REPO

SCENES = sorted((REPO / 'config').glob('*.yaml'))


def design_reads_by_key(path):
    """(line, text) of every `x[<str>]` or `x.get(<str>, ...)` whose `x` names a design (an
    identifier or attribute with 'design' in it: design, self.design, result.design, ...)."""
    tree = ast.parse(path.read_text(), str(path))
    found = []

    def names_a_design(node):
        words = [n.id for n in ast.walk(node) if isinstance(n, ast.Name)]
        words += [n.attr for n in ast.walk(node) if isinstance(n, ast.Attribute)]
        return any('design' in w.lower() and w != 'design_sources' for w in words)

    for node in ast.walk(tree):
        key = target = None
        if isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant):
            key, target = node.slice.value, node.value
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
              and node.func.attr == 'get' and node.args
              and isinstance(node.args[0], ast.Constant)):
            key, target = node.args[0].value, node.func.value
        if isinstance(key, str) and names_a_design(target):
            found.append((node.lineno, ast.unparse(node)))
    return found


def test_no_module_reads_a_design_by_string_key_outside_the_design_package():
    reads = {}
    for path in sorted((REPO / 'planter_ros').rglob('*.py')):
        if 'design' in path.relative_to(REPO / 'planter_ros').parts[:1]:
            continue
        hits = design_reads_by_key(path)
        if hits:
            reads[str(path.relative_to(REPO))] = hits
    assert reads == {}


def test_the_grep_finds_a_string_key_read(tmp_path):
    """The check above can fail: it sees the reads the issue counted (`design['l1']`,
    `design.get('mechanism')`, `self.design['plant_spacing']`)."""
    bad = tmp_path / 'bad.py'
    bad.write_text("def f(design, self):\n    return design['l1'], design.get('mechanism'), "
                   "self.design['plant_spacing'], report['design']['changes']\n")
    assert [text for _, text in design_reads_by_key(bad)] == [
        "design['l1']", "design.get('mechanism')", "self.design['plant_spacing']"]


@pytest.mark.parametrize('path', SCENES, ids=lambda p: p.name)
def test_every_shipped_scene_makes_a_typed_design_that_round_trips(path):
    design = design_for_scene(load_scene(path, 'design_node'))
    assert isinstance(design, (FiveBar, ThreeArm))
    text = to_json(design)
    assert from_json(text) == design
    assert json.loads(text) == to_dict(design)
    assert design.nominal_mechanism_speed == pytest.approx(
        2 * math.pi * design.nominal_ground_speed
        / (design.plants_per_revolution * design.plant_spacing))


def test_an_older_recordings_design_reads_with_the_later_fields_absent():
    """The committed sample bags' designs predate the nozzle width and the crop (a five-bar's
    D and d under the mechanism's own names too)."""
    old = {'mechanism': 'five_bar', 'plants_per_revolution': 1, 'depth': 0.06, 'spacing': 0.3,
           'l1': 0.1617, 'l2': 0.2095, 'method': 'exact', 'dyad_ratios': [1.4, 1.5, 1.3]}
    design = from_dict(old)
    assert (design.planting_depth, design.plant_spacing) == (0.06, 0.3)
    assert design.nozzle_width is None and design.crop is None
    assert design.dyad_ratios == (1.4, 1.5, 1.3)


@pytest.mark.parametrize('text, words', [
    ('not json', 'not JSON'),
    ('[1, 2]', 'design = list'),
    ('{"plant_spacing": 0.2}', 'mechanism = missing'),
    ('{"mechanism": "four_bar"}', "mechanism = 'four_bar' is out of range: allowed five_bar or "
                                  'three_arm'),
    ('{"mechanism": "five_bar", "plant_spacing": 0.2, "planting_depth": 0.045}',
     'five_bar without l1'),
    ('{"mechanism": "five_bar", "plant_spacing": "0.2", "planting_depth": 0.045, "l1": 0.1, '
     '"l2": 0.13}', "plant_spacing = '0.2' is out of range"),
    ('{"mechanism": "five_bar", "plant_spacing": 0.2, "planting_depth": NaN, "l1": 0.1, '
     '"l2": 0.13}', 'planting_depth = nan is out of range'),
    ('{"mechanism": "five_bar", "plant_spacing": 0.2, "planting_depth": 0.045, "l1": 0.1, '
     '"l2": 0.13, "nozzle_width": 3}', 'nozzle_width = 3 is out of range'),
    ('{"mechanism": "three_arm", "plant_spacing": 0.2, "planting_depth": 0.03, '
     '"tip_path": {"angle": [0, 1], "x": [0], "y": [0]}}', 'tip_path is not usable'),
    ('{"mechanism": "five_bar", "plants_per_revolution": 0, "plant_spacing": 0.2, '
     '"planting_depth": 0.045, "l1": 0.1, "l2": 0.13}', 'plants_per_revolution = 0'),
])
def test_a_malformed_or_foreign_message_is_one_line_naming_what_is_wrong(text, words):
    with pytest.raises(DesignMessageError) as err:
        from_json(text)
    message = str(err.value)
    assert message.startswith('design message: ') and words in message, message
    assert '\n' not in message
