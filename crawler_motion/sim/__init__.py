"""Simulated hardware on the CAN bus: the motor manager."""
