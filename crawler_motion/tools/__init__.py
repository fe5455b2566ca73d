"""Command-line tools: the crawler-motion CLI, console, demo, plots, benchmarks."""
