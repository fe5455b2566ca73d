"""The CAN driver: bus link, command gate, watchdog, feedback, diagnostics, ROS node."""
