"""Obstacles and their motion: Coal shapes, placements over time, clearance, and the scene file format."""
