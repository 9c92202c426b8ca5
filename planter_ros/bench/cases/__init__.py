"""Bench case modules; importing one registers its cases (see planter_ros.bench.registry)."""

# the submodules (imported by name, never here)
__all__ = ['analyze', 'cam', 'cdr', 'control_loop', 'drive', 'five_bar', 'footprint', 'replay',
           'sync', 'three_arm']
