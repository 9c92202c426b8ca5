"""`planter bench`: run time next to error against a high-precision reference.

`timing` measures (median and spread of repeats), `reference` computes mpmath references at
≥ 30 digits, `registry` holds the bench cases (one small function per row group, in `cases/`),
`report` formats the table and JSON, `host` names the computer it ran on. Nothing here imports
rclpy at module level.
"""

# the submodules (imported by name, never here)
__all__ = ['cases', 'host', 'reference', 'registry', 'report', 'timing']
