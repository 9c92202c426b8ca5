"""`planter simulate`: run (the options: cli/simulate.py)."""

import json
import sys

from planter_ros.analysis.simulate import (
    SeasonRequest, check_path, check_tray, season_machine, simulate_season)
from planter_ros.sim.season import bag_name
from planter_ros.sim.tray import TrayShares


def run(args):
    check_tray(args.empty_rate, args.double_rate)
    scene, rows = season_machine(args.scene, args.rows)     # a bad scene: one line, exit 2
    names = [bag_name(args.seed, k) for k in range(args.bags)]
    path = check_path(args.path, names)
    season = SeasonRequest(args.seed, args.duration, rows, scene,
                           TrayShares(args.empty_rate, args.double_rate))
    report, written, errors = simulate_season(path, names, season, args.workers, args.scheduler)
    if args.json:
        print(json.dumps({**report, 'runs': written}, indent=1, allow_nan=False))
    else:
        print(f'{len(written)} bags written to {path} ({rows} rows, {args.duration:g} s '
              f'each, seed {args.seed}): {report["messages"]} messages, {report["plants"]} '
              f'plants, {report["bytes"] / 1e6:.1f} MB')
        print(f'{report["seconds"]:.1f} s on {report["workers"]} worker(s): '
              f'{report["times_real_time"]:.0f}× real time')
    for name, error in errors:
        print(f'planter: error: {name} not written: {type(error).__name__}: {error}',
              file=sys.stderr)
    return 1 if errors else 0
