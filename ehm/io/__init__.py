"""Readers of range data and the map file format."""
