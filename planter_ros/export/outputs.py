"""The replay's exports for farm software (`planter replay --shapefile/--isoxml`): the plants
checked before any file is written, then each file written atomically, with a line for people
saying what was written (`write_each`: every output of a replay on its own, one failing never
keeping the others from being written). Errors are ExportError (one line)."""

from __future__ import annotations

from . import ExportError
from .runs import ExportRun

__all__ = ['replay_run', 'write_each', 'write_isoxml_output', 'write_shapefile_output']


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


def write_shapefile_output(run: ExportRun, path: str) -> str:
    """Write the Shapefile of a replay_run at `path`: the line for people."""
    from .shapefile import write_shapefile
    plants, placed = write_shapefile(path, [run])
    return f'Shapefile written to {path} ({plants} plants, {placed} with a map position)'


def write_isoxml_output(run: ExportRun, path: str) -> str:
    """Write the ISOXML task data of a replay_run at `path`: the line for people."""
    from .isoxml import write_isoxml
    tasks, logged, _ = write_isoxml(path, [run])
    return (f'ISOXML written to {path} ({tasks} task{"" if tasks == 1 else "s"}, {logged} '
            'plants in its time log)')


def write_each(outputs) -> tuple[list[str], list[str]]:
    """Write each output of `outputs` [(option, path, writer(path) -> line for people)] on its
    own: one that fails (a full disk, a bug on odd data) never keeps the others from being
    written. (lines for people, one line per output not written, naming its option)."""
    written, failed = [], []
    for option, path, write in outputs:
        try:
            written.append(write(path))
        except Exception as exc:
            text = str(exc).strip().splitlines()
            failed.append(f'{option} {path} not written: {type(exc).__name__}'
                          f'{": " + text[0] if text else ""}')
    return written, failed
