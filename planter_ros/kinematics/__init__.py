"""Pure numpy/scipy core: mechanism models, no ROS. Import submodules directly; this package
imports nothing heavy so a five-bar scene never loads the gear train or the optimiser."""
