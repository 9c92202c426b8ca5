"""The `planter` command line: one module per subcommand, heavy imports only inside run()."""
__all__ = ['analyze', 'bench', 'cam', 'demo', 'design_five_bar', 'design_three_arm', 'main',
           'optimize_three_arm', 'options', 'replay', 'simulate']
