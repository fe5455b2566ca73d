"""crawler_motion: motion controller of a four-legged underwater crawling robot on CAN motors.

The pure core (`model`, `motion`, `canbus`, and the cores of `planner`, `driver`, `sim`) imports
numpy, PyYAML, python-can and cantools only; the ROS 2 nodes live in `*/node.py` modules.

Importing the package sets ``OPENBLAS_NUM_THREADS=1`` unless the environment sets it (or numpy
was imported before): the package's matrices are small (the ZMP sway's ~150 unknowns, 3x3 leg
Jacobians), and OpenBLAS's worker threads spin between calls: 13 % of a core in
``controller_node`` on a 2-core machine, taken from the tick thread and the other processes.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

__version__ = "0.1.0"
