"""The robot's description: configuration, reference kinematics and URDF."""
