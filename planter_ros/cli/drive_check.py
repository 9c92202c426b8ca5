"""`planter drive check`: its options (the work: commission/drive_check.py)."""

import argparse

DEGREES = 5.0             # the move's size


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = ('Bring up each row\'s drive: its EDS and the start-up plan made from '
                          'it, its identity, enable with SYNC, a move of a few degrees, '
                          'disable (doc/drive.md, "Bringing up a new drive").')
    parser.add_argument('--machine', required=True, metavar='FILE', help='the machine file')
    parser.add_argument('--row', action='append', metavar='NAME',
                        help='check only this row (repeatable); default: every row')
    parser.add_argument('--simulated', action='store_true',
                        help='against simulated drives serving each row\'s EDS on a virtual '
                        'bus, as does a machine file whose can.interface is virtual')
    parser.add_argument('--degrees', type=float, default=DEGREES,
                        help=f'the move, mechanism degrees (default {DEGREES:g}; 0: none)')
