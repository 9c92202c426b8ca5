"""`planter simulate`'s engine: a season of simulated bags written on Dask (a local cluster or
an existing one), with progress; and the check of where they go."""

from dataclasses import dataclass
from pathlib import Path
import sys
import time

from planter_ros.cam import CamError
from planter_ros.config import ConfigError, from_mapping
from planter_ros.control.phase_lock import PhaseLockConfig
from planter_ros.design import design_for_scene
from planter_ros.output_files import OutputError, check_directory
from planter_ros.plausibility import bus_rows
from planter_ros.prediction import PredictionSettings
from planter_ros.scene import SceneError, open_scene
from planter_ros.scene.schedule import spacing_schedule
from planter_ros.sim.season import (
    SPEED_CHANGE_MAX, SceneMachine, bag_name, machine_cam, simulate_bag)
from planter_ros.sim.tray import TrayShares

from .engine import check_workers, cluster, completed
from .progress import Progress
from .task import model_version, warm_up

__all__ = ['SeasonRequest', 'check_path', 'check_tray', 'scene_machine', 'season_machine',
           'simulate_scene_bag', 'simulate_season']

DEFAULT_ROWS = 4


def check_tray(empty_rate, double_rate):
    """ConfigError (one line) for tray shares that add up to more than the whole tray."""
    if empty_rate + double_rate > 1.0:
        raise ConfigError(f'--empty-rate {empty_rate:g} + --double-rate {double_rate:g} = '
                          f'{100 * (empty_rate + double_rate):g} % of the cells: allowed '
                          'shares of the tray that add up to at most 1')


def season_machine(scene, rows):
    """(the scene file as an absolute path or None, the machine's rows) of `planter simulate`'s
    --scene and --rows (None: not given): ConfigError (one line) for both, or a bad scene."""
    if not scene:
        count = DEFAULT_ROWS if rows is None else rows
        refused = bus_rows(count)              # the rows' drives on the sync node's bus
        if refused:
            raise ConfigError(f'--rows = {count}: {refused}')
        return None, count
    if rows is not None:
        raise ConfigError(f'--rows = {rows} with --scene: allowed one of them (the scene\'s '
                          "rows are its machine's)")
    for warning in open_scene(scene).warnings:     # defaults taken, unusual values
        print(f'planter: warning: {warning}', file=sys.stderr)
    machine = scene_machine(scene)
    if machine.law.speed_profile == 'cam':
        try:
            for design in (machine.design, *(d for _, d in machine.schedule)):
                machine_cam(design, machine.law)
        except (ValueError, CamError) as exc:
            raise ConfigError(f'scene {scene}: speed_profile = cam cannot run: {exc}: allowed '
                              'a five-bar design the cam can plan, or speed_profile: '
                              'constant') from None
    return str(Path(scene).resolve()), len(machine.rows)


def scene_machine(scene):
    """The sim.season.SceneMachine of a scene file (SceneError, DesignError: one line)."""
    opened = open_scene(scene)
    design = opened.design()
    monitor = opened.parameters('monitor_node')
    params = opened.parameters('design_node')
    nominal = float(params.get('nominal_ground_speed', 0.2))
    schedule, current = [], design.plant_spacing
    for t, spacing in spacing_schedule(params, opened.path):
        if spacing != current:              # as the demo: the same spacing again changes nothing
            try:
                schedule.append((t, design_for_scene({**params, 'plant_spacing': spacing})))
            except ConfigError as exc:
                raise SceneError(f'scene {opened.path}: spacing_schedule {spacing} m at {t} s: '
                                 f'{exc}') from None
            current = spacing
    # cruise speeds around the nominal one, never above the scene's top ground speed once
    # the run's speed change (up to SPEED_CHANGE_MAX) is on top: the cam is planned for it
    ceiling = design.top_ground_speed / SPEED_CHANGE_MAX
    return SceneMachine(design, tuple(opened.rows()),
                        from_mapping(PredictionSettings, monitor), opened.acceptance(),
                        opened.antenna(), (min(0.75 * nominal, ceiling),
                                           min(1.5 * nominal, ceiling)),
                        from_mapping(PhaseLockConfig, opened.parameters('sync_node')),
                        tuple(schedule))


@dataclass(frozen=True)
class SeasonRequest:
    """The season `planter simulate` writes: runs of `duration` s drawn from the season of
    `seed`, each of a machine of `rows` rows or of the machine of the scene file `scene`
    (checked by the caller: season_machine; `rows` then its count), with a tray of `tray`'s
    empty and double shares."""

    seed: int
    duration: float
    rows: int | None
    scene: str | None = None
    tray: TrayShares = TrayShares()


def simulate_scene_bag(path, index, season):
    """sim.season.simulate_bag of run `index` of `season` (a SeasonRequest) at `path`, with the
    machine of its scene file (or its rows of the default machine): a task of `planter
    simulate` on a worker."""
    return simulate_bag(path, season.seed, index, season.duration,
                        scene_machine(season.scene) if season.scene else season.rows,
                        season.tray)


def check_path(path, names):
    """Refuse (OutputError) a PATH the bags cannot be written to: not a directory, not
    writable, a parent missing, or one of the bags already there (never overwritten)."""
    if path is None or str(path).strip() == '':
        raise OutputError("PATH is empty: allowed a directory for the bags (made if missing; "
                          "'.' for the working directory)")
    path = Path(path)
    if path.exists() or path.is_symlink():
        if not path.is_dir():
            raise OutputError(f'PATH = {path} exists and is not a directory: allowed a '
                              'directory for the bags')
        check_directory(path, 'PATH')
        taken = [name for name in names if (path / name).exists()]
        if taken:
            raise OutputError(f'PATH = {path} already holds {taken[0]}'
                              f'{f" and {len(taken) - 1} more" if len(taken) > 1 else ""}: '
                              'allowed another PATH or --seed (a recording is never '
                              'overwritten)')
    else:
        check_directory(path.parent if str(path.parent) else Path('.'), 'PATH', path)
    return path



def simulate_season(path: Path, names: list[str], season: SeasonRequest,
                    workers_wanted: int | None, scheduler: str | None):
    """Write the bags `names` (runs 0, 1, ... of `season`) under `path`: (report, the runs
    written, [(name, error)]). EngineError when the cluster cannot be had."""
    seed, duration, rows, scene, tray = (season.seed, season.duration, season.rows,
                                         season.scene, season.tray)
    version = model_version()
    where = scheduler or 'the local cluster'
    written, errors = [], []
    # --workers 1: the one worker in this process (no worker process to start)
    with cluster(workers_wanted, scheduler, in_process=workers_wanted == 1) as client:
        workers = check_workers(client, warm_up, version, where)
        path.mkdir(exist_ok=True)
        progress = Progress(len(names), what='bags', label='planter simulate')
        started = time.monotonic()
        try:
            arguments = [(str(path.resolve() / name), k, season)
                         for k, name in enumerate(names)]
            for i, result, error in completed(client, simulate_scene_bag, arguments):
                if error is None:
                    written.append(result)
                else:
                    errors.append((names[i], error))
                progress.update(len(written) + len(errors),
                                sum(r['duration'] for r in written), len(errors))
        finally:
            progress.close()
        seconds = time.monotonic() - started
    written.sort(key=lambda r: r['run'])
    run_seconds = sum(r['duration'] for r in written)
    size = sum((path / bag_name(seed, r['run'])).stat().st_size for r in written)
    report = {'path': str(path), 'bags': len(written), 'failed': len(errors),
              'seed': seed, 'duration': duration, 'rows': rows, 'scene': scene,
              'empty_rate': tray.empty_rate, 'double_rate': tray.double_rate,
              'workers': workers, 'seconds': seconds, 'bag_seconds': run_seconds,
              'times_real_time': run_seconds / seconds if seconds > 0 else None,
              'bytes': size, 'messages': sum(r['messages'] for r in written),
              'plants': sum(r['plants'] for r in written)}
    return report, written, errors
