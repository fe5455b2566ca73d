"""Leg kinematic calibration: error Jacobian, excitation poses, identification (RLS, DE)."""
