"""The work of each `planter` sub-command, `run(args) -> int`, one module per sub-command, its
imports at its top; `cli.main` imports only the one asked for, after its arguments parsed."""

# the sub-commands' modules (imported by name, never here)
__all__ = ['analyze', 'bench', 'cam', 'demo', 'design_five_bar', 'design_three_arm',
           'optimize_three_arm', 'replay', 'simulate']
