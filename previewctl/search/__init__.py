"""Search over the redundancy space: redundancy maps, scoring, global exploration and the 1-step GA."""
