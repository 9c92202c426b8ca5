"""`planter commission`: its options (the work: commission/command.py)."""

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = ('Commission the planting units: identify and check each drive '
                          'against the machine file, set its polarity, home it, measure its '
                          'phase offset, write the machine file and print a checklist '
                          '(doc/deploy.md, Commissioning).')
    parser.add_argument('--machine', required=True, metavar='FILE',
                        help='the machine file; rewritten with the polarity and phase found')
    parser.add_argument('--scene', metavar='FILE',
                        help='a scene to check against the machine first (rows, limits)')
    parser.add_argument('--row', action='append', metavar='NAME',
                        help='commission only this row (repeatable); default: every row')
    parser.add_argument('--simulated', action='store_true',
                        help='against simulated drives on a virtual bus (random mechanical '
                        'offset and polarity from --seed), as does a machine file whose '
                        'can.interface is virtual')
    parser.add_argument('--seed', type=_seed, default=0, metavar='N',
                        help='--simulated: seed of the mechanisms\' offsets and wiring, '
                        '0..2^32-1')
    parser.add_argument('--output', metavar='FILE.yaml',
                        help='write the machine file here instead of over --machine (checked '
                        'before any motion: an existing directory, a .yaml or .yml name)')


SEED_MAX = 2 ** 32 - 1


def _seed(text: str) -> int:
    """argparse `type=` of --seed: 0..2^32-1, one line naming the value otherwise."""
    try:
        value = int(text, 10)
    except ValueError:
        value = None
    if value is None or not 0 <= value <= SEED_MAX:
        shown = text if len(text) <= 40 else text[:37] + '...'
        raise argparse.ArgumentTypeError(f'--seed = {shown!r} is out of range: allowed '
                                         f'integer 0..{SEED_MAX}')
    return value
