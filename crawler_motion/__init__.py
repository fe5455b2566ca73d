"""crawler_motion: motion controller of a four-legged underwater crawling robot.

The pure core (`config`, `kinematics`, `trajectory`, `gait`, `urdf`, `protocol`) imports
numpy, PyYAML and cantools only; the ROS 2 nodes live in `*_node.py` modules.
"""

__version__ = "0.1.0"
