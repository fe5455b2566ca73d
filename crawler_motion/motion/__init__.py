"""Foot trajectories, gaits and the fast per-tick evaluator."""
