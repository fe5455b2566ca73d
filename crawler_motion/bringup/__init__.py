"""Bring-up: start, watch and stop the robot's processes together (``sim``, ``up``)."""
