"""A five-bar scene loads only what it uses: after a design (library call, or the command line,
in a fresh interpreter) no scipy, matplotlib, rclpy, mpmath, gear train or optimiser is in
sys.modules; matplotlib arrives only with --plot."""
import json
import os
import subprocess
import sys

from cli_helpers import REPO

HEAVY = ('scipy', 'matplotlib', 'rclpy', 'mpmath', 'hypothesis', 'yaml', 'can', 'canopen',
         'mcap', 'rosbags')
# the only planter_ros modules a five-bar design may load (a new module here is a new cost)
# (kinematics.arrays: the type names of the hints, numpy.typing: about 2 ms)
# (errors: the root of ConfigError, standard library only, 0.4 ms)
FIVE_BAR_MODULES = {'planter_ros', 'planter_ros.config', 'planter_ros.errors',
                    'planter_ros.kinematics', 'planter_ros.kinematics.arrays',
                    'planter_ros.kinematics.errors', 'planter_ros.kinematics.five_bar'}
# the command line adds its option checks: the scene's ranges and the output-path checks
CLI_MODULES = FIVE_BAR_MODULES | {'planter_ros.cli', 'planter_ros.cli.main',
                                  'planter_ros.cli.design_five_bar', 'planter_ros.cli.options',
                                  'planter_ros.cli.commands',     # the command's work
                                  'planter_ros.cli.commands.design_five_bar',
                                  'planter_ros.kinematics.design_inputs',
                                  'planter_ros.kinematics.mechanisms',
                                  'planter_ros.output_files', 'planter_ros.design',
                                  'planter_ros.design.text',
                                  'planter_ros.shipped',          # the version, for --version
                                  'planter_ros.dependencies',     # the extras it checks
                                  # plausibility of the speed against the sync law's limits
                                  'planter_ros.plausibility', 'planter_ros.control',
                                  'planter_ros.control.phase_lock', 'planter_ros.sensing',
                                  'planter_ros.sensing.ground_speed_filter',
                                  'planter_ros.control.odometer'}     # the phase lock's distance


def modules_after(code):
    """sys.modules of a fresh interpreter after running code."""
    env = dict(os.environ, PYTHONPATH=str(REPO))
    script = code + '\nimport json, sys\nprint(json.dumps(sorted(sys.modules)), file=sys.stderr)'
    out = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                         env=env, cwd=REPO, timeout=120)
    assert out.returncode == 0, out.stderr[-1000:]
    return set(json.loads(out.stderr.strip().splitlines()[-1]))


def heavy_in(modules):
    return sorted(m for m in modules if m.split('.')[0] in HEAVY)


def test_five_bar_design_scalar_and_batch_loads_nothing_heavy():
    mods = modules_after(
        'import numpy as np\n'
        'from planter_ros.kinematics.five_bar import design_five_bar, hole_geometry\n'
        'd = design_five_bar(0.045, 0.2, 0.05)\n'
        'b = design_five_bar(np.array([0.045, 0.05]), 0.2, 0.05)\n'
        'hole_geometry(d.l1, d.l2, d.depth, d.advance)\n')
    assert heavy_in(mods) == []
    assert {m for m in mods if m.startswith('planter_ros')} == FIVE_BAR_MODULES


def test_design_command_loads_nothing_heavy_and_no_other_mechanism():
    mods = modules_after(
        'from planter_ros.cli.main import main\n'
        "rc = main(['design', 'five-bar', '--depth', '0.045', '--spacing', '0.2', '--json',"
        " '--speed', '0.2'])\n"
        'assert rc == 0\n')
    assert heavy_in(mods) == []
    assert {m for m in mods if m.startswith('planter_ros')} <= CLI_MODULES


def test_matplotlib_loads_only_when_a_plot_is_asked_for(tmp_path):
    png = tmp_path / 'd.png'
    mods = modules_after(
        'from planter_ros.cli.main import main\n'
        f"rc = main(['design', 'five-bar', '--depth', '0.045', '--spacing', '0.2', '--plot',"
        f" {str(png)!r}])\n"
        'assert rc == 0\n')
    assert 'matplotlib' in mods and png.exists()
    assert {m.split('.')[0] for m in heavy_in(mods)} == {'matplotlib'}


def test_help_loads_no_numerics():
    mods = modules_after(
        'from planter_ros.cli.main import build_parser\n'
        'build_parser().format_help()\n')
    assert not any(m.split('.')[0] in ('numpy', 'scipy', 'matplotlib', 'rclpy', 'mpmath')
                   for m in mods)
