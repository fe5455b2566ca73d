"""The improved potential field: field, virtual goals, paths, following, coverage (pure)."""
