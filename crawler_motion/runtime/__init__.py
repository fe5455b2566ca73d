"""Real-time helpers: the steady-clock ticker and scheduling priority."""
