"""Navigation: the virtual body, heading rules and steering around mapped obstacles (pure)."""
