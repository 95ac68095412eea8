"""Simulation: a renderer of doors and calibration boards with exactly known truth, and the model check."""
