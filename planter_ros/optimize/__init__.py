"""Design optimisers (scipy), one module per mechanism."""

# the submodules (imported by name, never here)
__all__ = ['three_arm']
