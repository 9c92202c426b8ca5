"""Pure numpy/scipy core: mechanism models, no ROS. Import submodules directly; this package
imports nothing heavy so a five-bar scene never loads the gear train or the optimiser."""

# the submodules (imported by name, never here)
__all__ = ['arrays', 'design_inputs', 'errors', 'five_bar', 'mechanisms', 'planting',
           'three_arm']
