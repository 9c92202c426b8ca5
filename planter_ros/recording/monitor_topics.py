"""The monitor's output messages, built here once: for the live monitor node and for the bags the
season simulator writes as that node would have (sim.season), so both carry the same bytes.

* `plants`: std_msgs/Float64MultiArray, dim[0] 'plant' × dim[1] labelled with the field names
  (prediction.PLANT_FIELDS, SI), one line per plant;
* `spacing_quality`: std_msgs/Float64MultiArray, dim[0] 'row' × dim[1] labelled 'row' and the
  index names (prediction.QUALITY_FIELDS), the machine's line first (row -1); an index that is
  undefined is NaN.

Replay reads `plants` back by its labels (recording.replay), so a reader of an older bag with
fewer fields still finds each one.
"""

from collections.abc import Mapping, Sequence
import math

from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from planter_ros.prediction import PLANT_FIELDS, QUALITY_FIELDS, Plants

__all__ = ['PLANTS_LABEL', 'QUALITY_LABEL', 'plants_message', 'quality_message']

PLANTS_LABEL = ','.join(PLANT_FIELDS)
QUALITY_LABEL = ','.join(('row',) + QUALITY_FIELDS)


def _table_message(lines: str, labels: str, n: int, f: int,
                   data: list[float]) -> Float64MultiArray:
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label=lines, size=n, stride=n * f),
                      MultiArrayDimension(label=labels, size=f, stride=f)]
    msg.data = data
    return msg


def plants_message(plants: Plants) -> Float64MultiArray:
    """The `plants` message of a batch of plants."""
    table = plants.table()
    n, f = table.shape
    return _table_message('plant', PLANTS_LABEL, n, f, table.ravel().tolist())


def quality_message(qualities: Sequence[tuple[int, Mapping[str, float | int | None]]]
                    ) -> Float64MultiArray:
    """The `spacing_quality` message of [(row index, SpacingQuality.result())]."""
    table = [[float(row)] + [math.nan if (v := q[f]) is None else float(v)
                             for f in QUALITY_FIELDS]
             for row, q in qualities]
    return _table_message('row', QUALITY_LABEL, len(table), len(QUALITY_FIELDS) + 1,
                          [v for line in table for v in line])
