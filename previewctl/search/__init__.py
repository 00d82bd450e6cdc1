"""TODO: search."""
