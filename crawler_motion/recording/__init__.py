"""Recording and viewing runs: ROS 2 MCAP recorder, CAN log, post-run report, Foxglove view."""
