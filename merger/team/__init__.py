"""Merging a team's maps."""
