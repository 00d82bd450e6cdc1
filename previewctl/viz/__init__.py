"""TODO: viz."""
