"""planter_ros: design and drive the planting unit of a seedling transplanter."""

# the subpackages and modules (imported by name, never here)
__all__ = ['analysis', 'bench', 'cam', 'cli', 'config', 'control', 'dds_domain', 'demo', 'design',
           'diagnostics', 'drive', 'errors', 'export', 'geo', 'interfaces', 'kinematics', 'nodes',
           'optimize', 'output_files', 'plots', 'prediction', 'recording', 'rows', 'safe_yaml',
           'scene', 'sensing', 'shipped', 'sim', 'stop_signals']
