"""crawler_motion: motion controller of a four-legged underwater crawling robot on CAN motors.

The pure core (`model`, `motion`, `canbus`, and the cores of `planner`, `driver`, `sim`) imports
numpy, PyYAML, python-can and cantools only; the ROS 2 nodes live in `*/node.py` modules.
"""

__version__ = "0.1.0"
