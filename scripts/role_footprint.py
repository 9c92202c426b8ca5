#!/usr/bin/env python3
"""Measure what each install role costs (doc/deploy.md, "Install by role"): for each role a fresh
venv gets `pip install --no-compile .[role]` (the pins of requirements.txt as constraints), then
its installed size (MB of the venv's site-packages), its number of distributions, and the import
time of each node's module and of the command process (best of 3, a warm file cache, no .pyc
files written beforehand: the first import of a fresh install compiles, the figure is a later
start's).

    python3 scripts/role_footprint.py [--roles base,analysis,dev] [--keep DIR]

Prints a Markdown table. Takes minutes (the installs).
"""
import argparse
import os
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile
import time

REPO = Path(__file__).resolve().parents[1]
MODULES = ('planter_ros.nodes.design_node', 'planter_ros.nodes.sync_node',
           'planter_ros.nodes.monitor_node', 'planter_ros.nodes.ground_speed_node',
           'planter_ros.command.process')


def run(*args, **kwargs):
    return subprocess.run(args, check=True, capture_output=True, text=True, **kwargs)


def size_mb(path):
    return sum(f.stat().st_size for f in Path(path).rglob('*') if f.is_file()
               and not f.is_symlink()) / 1e6


def constraints(work):
    """requirements.txt's pins as a constraints file (pip takes no extras there)."""
    import re
    path = work / 'constraints.txt'
    lines = [re.sub(r'\[[^]]*\]', '', line.split('#', 1)[0]).strip()
             for line in (REPO / 'requirements.txt').read_text().splitlines()]
    path.write_text('\n'.join(line for line in lines if line) + '\n')
    return path


def measure(role, work):
    venv = work / f'venv-{role}'
    run(sys.executable, '-m', 'venv', str(venv))
    python = venv / 'bin' / 'python'
    target = str(REPO) if role == 'base' else f'{REPO}[{role}]'
    t0 = time.monotonic()
    run(str(python), '-m', 'pip', 'install', '--quiet', '--no-compile',
        '--disable-pip-version-check', '-c', str(constraints(work)), target)
    install_s = time.monotonic() - t0
    site = next((venv / 'lib').glob('python3*/site-packages'))
    listed = run(str(python), '-m', 'pip', 'list', '--format=freeze',
                 '--disable-pip-version-check').stdout.split()
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    env.pop('PYTHONPATH', None)
    imports = {}
    for module in MODULES:
        run(str(python), '-c', f'import {module}', env=env, cwd=work)   # compiles once
        best = float('inf')
        for _ in range(3):
            t0 = time.monotonic()
            run(str(python), '-c', f'import {module}', env=env, cwd=work)
            best = min(best, time.monotonic() - t0)
        imports[module.rsplit('.', 1)[-1]] = best
    return {'role': role, 'mb': size_mb(site), 'dists': len(listed), 'install_s': install_s,
            'imports': imports}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--roles', default='base,analysis,dev')
    parser.add_argument('--keep', metavar='DIR', help='make the venvs here and keep them')
    args = parser.parse_args()
    work = Path(args.keep or tempfile.mkdtemp(prefix='planter-roles-'))
    work.mkdir(parents=True, exist_ok=True)
    rows = []
    try:
        for role in args.roles.split(','):
            row = measure(role, work)
            rows.append(row)
            print(f'{role}: {row}', file=sys.stderr, flush=True)
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    names = list(rows[0]['imports'])
    print('| install | site-packages | distributions | ' + ' | '.join(
        f'import {n}' for n in names) + ' |')
    print('|---|---|---|' + '---|' * len(names))
    for row in rows:
        what = 'base' if row['role'] == 'base' else f"base + {row['role']}"
        print(f"| {what} | {row['mb']:.0f} MB | {row['dists']} | " + ' | '.join(
            f"{row['imports'][n]:.2f} s" for n in names) + ' |')


if __name__ == '__main__':
    main()
