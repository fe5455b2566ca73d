"""Operator commands, the planner state machine and its ROS node."""
