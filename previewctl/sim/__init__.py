"""TODO: sim."""
