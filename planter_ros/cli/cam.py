"""`planter cam five-bar`: one mechanism, several spacings and ground speeds, constant sun-bar
speed beside the electronic cam (planter_ros.cam): sweep, hole, tilt and the drive's loads
against its limits; a table, JSON or a plot.

Depth, spacings, speeds, hole ratio and nozzle width take the scene's ranges; the drive options
are the fields of `cam.DriveLimits` with their own ranges."""

from planter_ros.cam.drive import DriveLimits
from planter_ros.cli.main import BadInput
from planter_ros.cli.options import output_file, shown, spec_option
from planter_ros.config import specs
from planter_ros.kinematics.design_inputs import DesignInputs

MAX_SPACINGS = 20
MAX_SPEEDS = 10
RULE_WORDS = {'design-speed': 'design_speed', 'zero-slip': 'zero_slip'}


def list_option(cls, name, option, most):
    """argparse `type=` for a comma-separated list of `option` values, each checked like
    spec_option; at most `most` values, no repeats (kept in the order given)."""
    one = spec_option(cls, name, option)

    def parse(text):
        parts = text.split(',')
        if not 1 <= len(parts) <= most:
            raise BadInput(f'{option} = {shown(text)} has {len(parts)} values: allowed 1..{most} '
                           'comma-separated values')
        values = [one(p.strip()) for p in parts]
        return list(dict.fromkeys(values))
    parse.__name__ = name
    return parse


def _rule(text):
    if text not in RULE_WORDS:
        raise BadInput(f'--rule = {shown(text)} is not a rule: allowed '
                       f'{" or ".join(RULE_WORDS)}')
    return RULE_WORDS[text]


def add_arguments(parser):
    parser.add_argument('--depth', type=spec_option(DesignInputs, 'planting_depth', '--depth'),
                        required=True, metavar='M', help='planting depth D (m), e.g. 0.045')
    parser.add_argument('--design-spacing', required=True, metavar='M',
                        type=spec_option(DesignInputs, 'plant_spacing', '--design-spacing'),
                        help='the spacing the mechanism is designed for (m): its bars come from '
                             'the five-bar reverse design at D, this spacing and the hole ratio')
    parser.add_argument('--spacing', required=True, metavar='M[,M…]',
                        type=list_option(DesignInputs, 'plant_spacing', '--spacing',
                                         MAX_SPACINGS),
                        help=f'the spacings to plant (m), up to {MAX_SPACINGS}, e.g. 0.15,0.3,0.5')
    parser.add_argument('--speed', required=True, metavar='M/S[,…]',
                        type=list_option(DesignInputs, 'nominal_ground_speed', '--speed',
                                         MAX_SPEEDS),
                        help=f'top ground speeds (m/s), up to {MAX_SPEEDS}: the cam is planned '
                             'for each as the top speed')
    parser.add_argument('--hole-ratio', type=spec_option(DesignInputs, 'hole_ratio',
                                                         '--hole-ratio'),
                        default=0.05, metavar='K',
                        help='the design hole over depth, k = t/D (default 0.05)')
    parser.add_argument('--nozzle-width', type=spec_option(DesignInputs, 'nozzle_width',
                                                           '--nozzle-width'),
                        default=0.0, metavar='M',
                        help="the nozzle's width along the row (m), added to the tip's sweep "
                             'for the hole (default 0: the hole is the sweep)')
    parser.add_argument('--rule', type=_rule, default='design-speed',
                        metavar='design-speed|zero-slip',
                        help='the cam in the soil: design-speed (the mechanism\'s own '
                             'zero-speed ratio: the design hole, no tilt) or zero-slip (a '
                             'point hole, far larger loads); default design-speed')
    limits = parser.add_argument_group('drive and limits (default: a 750 W servo, 20:1 '
                                       'planetary gearbox; doc/cam.md)')
    for spec in specs(DriveLimits):
        option = '--' + spec.name.replace('_', '-')
        limits.add_argument(option, dest=f'drive_{spec.name}',
                            metavar=spec.unit.upper().replace(' ', '·') or 'X',
                            type=spec_option(DriveLimits, spec.name, option),
                            help=f'{spec.describe()} (default {spec.default:.6g})'
                            .replace('%', '%%'))
    parser.add_argument('--json', action='store_true', help='print JSON (SI units) for machines')
    parser.add_argument('--plot', metavar='FILE.png', type=output_file('--plot', ('.png',)),
                        help='draw θ(s) and the tip in the soil for both profiles, sweep and '
                             'tilt against spacing, the feasibility map and the loads')
