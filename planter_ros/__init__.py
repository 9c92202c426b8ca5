"""planter_ros: design and drive the planting unit of a seedling transplanter."""

# the subpackages and modules (imported by name, never here)
__all__ = ['analysis', 'bench', 'cam', 'cli', 'command', 'commission', 'config', 'control', 'demo',
           'dependencies', 'design', 'diagnostics', 'drive', 'errors', 'export', 'geo', 'host',
           'interfaces', 'kinematics', 'nodes', 'optimize', 'output_files', 'plausibility',
           'plots', 'prediction', 'recording', 'rows', 'safe_yaml', 'scene', 'sensing', 'shipped',
           'sim', 'simdrive']
