"""`planter analyze`: run (the options: cli/analyze.py)."""

import json
import sys

from planter_ros.analysis import season as seasons
from planter_ros.analysis.bags import find_bags
from planter_ros.analysis.engine import check_workers, cluster
from planter_ros.analysis.progress import Progress
from planter_ros.analysis.task import model_version, warm_up
from planter_ros.cli.commands.replay import fallback_design, settings_overrides
from planter_ros.cli.main import BadInput
from planter_ros.export.season import format_exports
from planter_ros.plots.season import season_outputs


def run(args):
    out = seasons.check_out(args.out)
    design = fallback_design(args)
    overrides = settings_overrides(args)
    ignored: list[tuple[str, str]] = []
    bags = find_bags(args.paths, skip=[out], ignored=ignored)    # BagSearchError: exit 2
    for path, why in ignored:
        print(f'planter: warning: {path} is {why}, not a bag: skipped', file=sys.stderr)
    if not bags:
        raise BadInput(f'PATH = {" ".join(args.paths)} holds no bag: allowed .mcap files and '
                       'directories holding .mcap files or rosbag2 bag directories')
    version = model_version()
    root = seasons.analysed_root(args.paths)
    with seasons.Season(out, root) as season:
        keys, skipped = season.plan(seasons.bag_keys(bags, root), version,
                                    seasons.options_key(overrides, design), args.force)
        renamed = season.apply_renames()
        report = seasons.Report(out=str(out))
        if keys:
            where = args.scheduler or 'the local cluster'
            # --workers 1: the one worker in this process (no worker process to start)
            with cluster(args.workers, args.scheduler,               # EngineError: exit 2
                         in_process=args.workers == 1) as client:
                workers = check_workers(client, warm_up, version, where)
                season.clear(keys)
                progress = Progress(len(keys), label='planter analyze')
                report = seasons.run(season, client, keys, overrides, design, progress)
                report.workers = workers
        exports, table, html, failed = season_outputs(out, force=bool(keys) or renamed)
    report.found, report.skipped = len(bags) - len(season.copies), skipped
    report.copies = season.copies
    if args.json:
        print(json.dumps({**report.as_json(), 'exports': exports,
                          'report': html and str(html)}, indent=1, allow_nan=False))
    else:
        print(seasons.format_report(report) + (f'\n{table}\nseason report: {html}' if html
                                               else ''))
        if exports:
            print(format_exports(exports))
    for line in seasons.notices(report, exports, failed):
        print(line, file=sys.stderr)
    return 1 if report.not_done or failed else 0
