"""Fleets: Monte Carlo over fabrication tolerances and temperature (issue 16)."""
