"""Run the `planter` command line in a subprocess, as a user would (`run_planter`), or in the
test's own process (`planter_here`) where what a command prints and writes is the question, not
its process: no interpreter to start, the imports, caches and model version loaded once."""
import contextlib
import io
import os
import subprocess
import sys
from pathlib import Path

from planter_ros.cli.main import main

REPO = Path(__file__).resolve().parents[1]


def run_planter(*args, timeout=120, cwd=None):
    env = dict(os.environ, PYTHONPATH=str(REPO), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    return subprocess.run([sys.executable, '-m', 'planter_ros.cli', *map(str, args)],
                          capture_output=True, text=True, timeout=timeout, env=env,
                          cwd=cwd or REPO)


def planter_here(*args):
    """`planter ARGS` called in this process, its output captured: what run_planter returns
    (returncode, stdout, stderr); argparse's refusals (SystemExit) give their exit code."""
    words = [str(a) for a in args]
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(words)
        except SystemExit as exc:
            code = exc.code
    return subprocess.CompletedProcess(['planter', *words], code, out.getvalue(),
                                       err.getvalue())
