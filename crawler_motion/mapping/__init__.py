"""Terrain mapping: the elevation grid, Kalman cell fusion and obstacle cells (pure numpy)."""
