"""Design optimisers (scipy), one module per mechanism."""
