"""`planter demo`: run (the options: cli/demo.py)."""

from planter_ros.cli.demo import options
from planter_ros.demo.run import prepare


def run(args):
    return prepare(options(args)).run()
