"""The replay's exports for farm software (`planter replay --shapefile/--isoxml`): the plants
checked before any file is written, then each file written atomically, with a line for people
saying what was written. Errors are ExportError (one line)."""

from __future__ import annotations

from . import ExportError
from .runs import ExportRun

__all__ = ['replay_run', 'write_outputs']


def replay_run(result, shapefile: str | None, isoxml: str | None) -> ExportRun | None:
    """The replay's plants for the Shapefile and ISOXML outputs (None without either), checked
    first: ExportError for plants a format cannot hold."""
    if not (shapefile or isoxml):
        return None
    from .isoxml import check_run
    from .runs import run_of_replay
    run = run_of_replay(result)
    if isoxml:
        try:
            check_run(run)
        except ExportError as exc:
            raise ExportError(f'--isoxml: {exc}') from None
    return run


def write_outputs(run: ExportRun | None, shapefile: str | None,
                  isoxml: str | None) -> list[str]:
    """Write the Shapefile and the ISOXML task data of a replay_run: lines for people."""
    if run is None:
        return []
    written = []
    if shapefile:
        from .shapefile import write_shapefile
        plants, placed = write_shapefile(shapefile, [run])
        written.append(f'Shapefile written to {shapefile} ({plants} plants, {placed} with a '
                       'map position)')
    if isoxml:
        from .isoxml import write_isoxml
        tasks, logged, _ = write_isoxml(isoxml, [run])
        written.append(f'ISOXML written to {isoxml} ({tasks} task{"" if tasks == 1 else "s"}, '
                       f'{logged} plants in its time log)')
    return written
