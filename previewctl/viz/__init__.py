"""Figures: drawing helpers, run figures (strobe, S, clearance, error, GIF) and landscape maps."""
