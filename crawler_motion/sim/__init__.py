"""Simulated hardware on the CAN bus: the joint-only motor manager and the seabed physics."""
