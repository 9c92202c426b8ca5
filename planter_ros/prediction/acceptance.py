"""A crop's acceptance limits and the judgement of a run against them: does the run meet what
the crop needs, and if not, which index failed, on which row, by how much.

The limits are scene values (parameters of the monitor node, recorded in its bags, so a replay
judges a bag against the limits of its own run unless a scene is given). All fractions 0..1,
hole width in m:

* min_quality_of_feed    quality of feed index (ISO 7256-1 single spacings)    >= limit
* max_multiple_index     multiple index (x <= 0.5 d)                           <= limit
* max_miss_index         miss index (x > 1.5 d)                                <= limit
* max_precision          precision, the CV of the single spacings             <= limit
* min_uprightness_rate   share of plants upright (the monitor's threshold)     >= limit
* max_hole_width         mean hole width of the row                             <= limit
                         (0: not judged, the default: no standard gives one)

Where the defaults come from (doc/planting_quality.md#acceptance-limits): the four spacing
limits are those of DB32/T 1023-2007 (Jiangsu provincial standard for the operation quality of
maize precision seeders: spacing pass index >= 80 %, CV of the passing spacings <= 30 %,
multiple and miss indices <= 8 % each). It is a seeder standard, not a transplanter one: no
national transplanter test standard's text could be confirmed, so these are a stand-in a crop's
scene should replace. The uprightness default (>= 90 %) is this project's assumption: the
rice-transplanting literature counts a seedling at < 30 deg to the ground as fallen (the
monitor's default threshold), but no confirmed standard gives a rate.

Each planting row is judged on its own (a row's failure names the row); a machine with one
unnamed row is judged as a whole. A row (or machine) that put no seedling in the ground (no
planting instant, or only empty cups) fails (`planted`): a run that planted nothing never
passes. An index a row that planted cannot give (no spacings, fewer than two single spacings
for the CV) is listed as not judged, never as passed or failed. Pure: no ROS, no numpy.
"""

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
import math
from typing import Any, TypedDict

from planter_ros.config import as_dict, check, setting
from planter_ros.kinematics.errors import DesignError

__all__ = ['ACCEPTANCE_SOURCE', 'AcceptanceLimits', 'Acceptance', 'LIMITS', 'judge_acceptance',
           'format_acceptance', 'acceptance_failures']

ACCEPTANCE_SOURCE = ('spacing limits: DB32/T 1023-2007 (a provincial seeder standard, a '
                     'stand-in: no transplanter standard confirmed); uprightness >= 90 %: '
                     'assumption; hole width: set per crop')


@dataclass(frozen=True)
class AcceptanceLimits:
    """A crop's acceptance limits (SI; fractions 0..1): module doc."""

    min_quality_of_feed: float = setting(
        0.80, 'acceptance: least quality of feed index (ISO 7256-1 single spacings) of each '
        'row; default from DB32/T 1023-2007 (seeder standard, stand-in)', range=(0.0, 1.0))
    max_multiple_index: float = setting(
        0.08, 'acceptance: largest multiple index (x <= 0.5 d) of each row; default from '
        'DB32/T 1023-2007 (seeder standard, stand-in)', range=(0.0, 1.0))
    max_miss_index: float = setting(
        0.08, 'acceptance: largest miss index (x > 1.5 d) of each row; default from '
        'DB32/T 1023-2007 (seeder standard, stand-in)', range=(0.0, 1.0))
    max_precision: float = setting(
        0.30, 'acceptance: largest precision (CV of the single spacings) of each row; default '
        'from DB32/T 1023-2007 (seeder standard, stand-in)', range=(0.0, 10.0))
    min_uprightness_rate: float = setting(
        0.90, 'acceptance: least share of upright plants of each row; default an assumption '
        '(no standard rate confirmed)', range=(0.0, 1.0))
    max_hole_width: float = setting(
        0.0, "acceptance: largest mean hole width of each row; 0: not judged (no standard "
        'gives one; set it per crop)', unit='m', range=(0.0, 2.0))

    def __post_init__(self) -> None:
        check(self, DesignError.from_message)


class Failure(TypedDict):
    """An index a row failed: its value against the limit, and the line for people."""

    row: str
    index: str
    value: float
    limit: float
    text: str


class NotJudged(TypedDict):
    """An index a row cannot give (no value), and the line for people."""

    row: str
    index: str
    text: str


class Acceptance(TypedDict):
    """A run judged against a crop's limits (judge_acceptance): JSON-ready."""

    passed: bool
    failed: list[Failure]
    not_judged: list[NotJudged]
    limits: dict[str, Any]


# (limit field, figure name for people, where the figure is in a summary, sense, percent?)
LIMITS: tuple[tuple[str, str, tuple[str, ...], str, bool], ...] = (
    ('min_quality_of_feed', 'quality of feed', ('spacing_quality', 'quality_of_feed_index'),
     '>=', True),
    ('max_multiple_index', 'multiple index', ('spacing_quality', 'multiple_index'), '<=', True),
    ('max_miss_index', 'miss index', ('spacing_quality', 'miss_index'), '<=', True),
    ('max_precision', 'precision (CV)', ('spacing_quality', 'precision'), '<=', True),
    ('min_uprightness_rate', 'uprightness rate', ('uprightness_rate',), '>=', True),
    ('max_hole_width', 'hole width (mean)', ('hole_width_mean',), '<=', False),
)


def _figure(summary: Mapping[str, Any], path: tuple[str, ...]) -> Any:
    value: Any = summary
    for key in path:
        if not isinstance(value, dict):
            return None
        value = value.get(key)
    return value


def _text(value: float, percent: bool) -> str:
    return f'{100 * value:.1f} %' if percent else f'{1e3 * value:.1f} mm'


def judge_acceptance(limits: AcceptanceLimits,
                     judged: Sequence[tuple[str, Mapping[str, Any]]]) -> Acceptance:
    """Judge each (row label, summary) of `judged` (summaries as prediction.summarize gives
    them; label '' for a machine judged as a whole) against `limits`: {'passed': bool,
    'failed': [{row, index, value, limit, text}], 'not_judged': [{row, index, text}],
    'limits': {field: value}}. JSON-ready."""
    failed: list[Failure] = []
    not_judged: list[NotJudged] = []
    for label, summary in judged:
        where = f'row {label}: ' if label else ''
        instants = summary.get('plants')               # (None: a summary that does not say)
        seedlings = (summary.get('instants') or {}).get('seedlings', instants)
        if seedlings is not None and seedlings == 0:
            failed.append({'row': label, 'index': 'planted', 'value': 0.0, 'limit': 1.0,
                           'text': f'{where}planted nothing ({instants} planting instants, '
                                   'no seedling in the ground)'})
            continue
        for name, words, path, sense, percent in LIMITS:
            limit = float(getattr(limits, name))
            if name == 'max_hole_width' and limit <= 0.0:
                continue
            value = _figure(summary, path)
            if value is None or not math.isfinite(float(value)):
                not_judged.append({'row': label, 'index': name,
                                   'text': f'{where}{words} not judged (no value)'})
                continue
            value = float(value)
            ok = value >= limit if sense == '>=' else value <= limit
            if not ok:
                failed.append({'row': label, 'index': name, 'value': value, 'limit': limit,
                               'text': f'{where}{words} {_text(value, percent)} '
                                       f'{"<" if sense == ">=" else ">"} {_text(limit, percent)}'
                                       f' ({name})'})
    return {'passed': not failed, 'failed': failed, 'not_judged': not_judged,
            'limits': as_dict(limits)}


def acceptance_failures(acceptance: Mapping[str, Any] | None) -> list[str]:
    """The one-line texts of what failed (empty when it passed or was not judged); an
    Acceptance, or one read back from JSON."""
    failed = (acceptance or {}).get('failed', [])
    return [str(item['text']) for item in failed]


def format_acceptance(acceptance: Mapping[str, Any], source: str = '') -> str:
    """One line for people: PASS, or FAIL and what failed."""
    head = 'acceptance' + (f' ({source})' if source else '')
    if acceptance['passed']:
        skipped = acceptance.get('not_judged') or []
        tail = f' ({len(skipped)} figure(s) not judged)' if skipped else ''
        return f'{head}: PASS, every index within the crop\'s limits{tail}'
    return f'{head}: FAIL: ' + '; '.join(acceptance_failures(acceptance))
