"""The process stack launcher and bus tap shared by the demo, benchmarks and tests."""
