"""Simulation: scenarios (TOML), the closed loop, and the run log."""
