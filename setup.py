"""Packaging of crawler_motion (ament_python; also installable with plain pip)."""

from glob import glob
from os.path import isfile

from setuptools import find_packages, setup

PACKAGE = "crawler_motion"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        # Files only: the worlds directory is installed as its own entry below.
        (f"share/{PACKAGE}/config", sorted(f for f in glob("config/*") if isfile(f))),
        (f"share/{PACKAGE}/config/worlds", sorted(glob("config/worlds/*.xml"))),
    ],
    python_requires=">=3.10",
    install_requires=[
        "numpy>=1.24",
        "pyyaml>=6",
        "python-can>=4.3",
        "cantools>=39",
        "msgpack>=1.0",
        "matplotlib>=3.7",
        # the seabed simulator: physics, pictures (headless EGL needs PyOpenGL)
        "mujoco>=3",
        "Pillow",
        "PyOpenGL",
        # recordings (ROS 2 MCAP), the live view in Foxglove
        "mcap>=1.2",
        "mcap-ros2-support>=0.5",
        "foxglove-sdk>=0.30",
    ],
    extras_require={
        # rosbags: the soak opens its recording with an independent reader
        "test": ["pytest>=7", "hypothesis>=6.80", "ruff>=0.5", "websockets>=12",
                 "rosbags>=0.10"],
        # `crawler-motion tune-smooth` only
        "tune": ["scipy>=1.10"],
    },
    zip_safe=True,
    maintainer="crawler_motion maintainers",
    maintainer_email="maintainers@crawler-motion.invalid",
    description="Motion controller of a four-legged underwater crawling robot on CAN motors.",
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={
        "console_scripts": [
            "crawler-motion = crawler_motion.tools.cli:main",
            "planner_node = crawler_motion.planner.node:main",
            "motor_manager_sim = crawler_motion.sim.manager_cli:main",
            "driver_node = crawler_motion.driver.node:main",
            "controller_node = crawler_motion.controller.node:main",
            "seabed_sim = crawler_motion.sim.seabed.node:main",
            "terrain_mapper = crawler_motion.mapping.node:main",
            "navigator = crawler_motion.navigation.node:main",
            "recorder = crawler_motion.recording.recorder:node_main",
        ],
    },
)
