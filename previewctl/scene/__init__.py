"""TODO: scene."""
