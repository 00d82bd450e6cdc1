"""TODO: robot."""
