"""Evaluation: scenarios, routes, metrics against the simulator's ground truth."""
