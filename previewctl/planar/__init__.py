"""TODO: planar."""
