"""The `planter` command line: per subcommand its options here, its work in `commands/`."""
__all__ = ['analyze', 'bench', 'cam', 'commands', 'commission', 'demo', 'design_five_bar',
           'design_three_arm', 'drive_check', 'main', 'optimize_three_arm', 'options', 'replay',
           'simulate']
