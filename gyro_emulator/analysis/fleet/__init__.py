"""Fleets: Monte Carlo over fabrication tolerances and temperature."""
