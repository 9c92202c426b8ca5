"""Figures for people (matplotlib, Agg backend); imported only when a plot is asked for."""

# the submodules (imported by name, never here)
__all__ = ['bench', 'cam', 'five_bar', 'replay', 'three_arm']
