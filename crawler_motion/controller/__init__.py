"""The composed controller: planner and driver in one process, each tick handed to the bus."""
