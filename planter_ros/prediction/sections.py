"""A row's section switched off and on again: a break in that row's spacing sequence.

While a row's section is off its mechanism stands still and the machine drives on, so the first
plant after the section is on again would read as a miss (and the row starts a new grid from
the switch-on point anyway). The sync node publishes every row's section state (the `sections`
topic, interfaces.SECTIONS); from those states in time order `SectionBreaks` finds each instant
a row was switched on again after being off: a break (start = end = that instant). The
prediction treats it like a gap in its inputs: the first plant after it has no spacing
(`PlantPredictor.add_break`, `RowInputs.breaks` of `predict_plants`), while a plant the
mechanism could no longer stop in front of the soil after the switch-off keeps its own.
The live monitor feeds the states as they come, replay all at once (`section_breaks`); both
through the same class. Pure Python, no ROS.
"""

from collections.abc import Iterable, Mapping

__all__ = ['SectionBreaks', 'section_breaks']


class SectionBreaks:
    """The breaks of every row, from its section states in time order."""

    def __init__(self) -> None:
        self._off: set[str] = set()             # rows whose last state said off

    def update(self, t: float, states: Mapping[str, bool]) -> list[tuple[str, float, float]]:
        """The rows' states {row name: on} at time `t` (s); returns the breaks they make, as
        (row name, start, end)."""
        done = []
        for row, on in states.items():
            if not on:
                self._off.add(row)
            elif row in self._off:
                self._off.discard(row)
                done.append((row, t, t))
        return done


def section_breaks(reports: Iterable[tuple[float, Mapping[str, bool]]]
                   ) -> dict[str, list[tuple[float, float]]]:
    """{row name: [(start, end), ...]} of reports [(t, {row name: on})] in time order."""
    tracker = SectionBreaks()
    breaks: dict[str, list[tuple[float, float]]] = {}
    for t, states in reports:
        for row, start, end in tracker.update(t, states):
            breaks.setdefault(row, []).append((start, end))
    return breaks
