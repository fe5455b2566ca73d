"""``config/params.yaml`` configures every node with ``--ros-args --params-file``, also under a
namespace: each node (in this process, one after the other) takes the whole file, types and
all, and a value changed in its section reaches it; ``motor_manager_sim`` reads it too."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

rclpy = pytest.importorskip("rclpy")

from crawler_motion.driver.node import DriverNode  # noqa: E402
from crawler_motion.mapping.node import TerrainMapperNode  # noqa: E402
from crawler_motion.navigation.node import NavigatorNode  # noqa: E402
from crawler_motion.planner.node import PlannerNode  # noqa: E402
from crawler_motion.runtime.ros_args import parse_ros_args  # noqa: E402
from crawler_motion.sim.manager_parameters import NODE_NAME, manager_flags  # noqa: E402
from crawler_motion.testing.bus import free_udp_port  # noqa: E402
from crawler_motion.tools.param_docs import PARAMS_OUT  # noqa: E402

SHIPPED = Path(__file__).resolve().parents[2] / PARAMS_OUT
#: Per node section: (node factory, parameter changed in the copy, its new value).
CHANGES: dict[str, tuple[Callable[[], Any], str, Any]] = {
    "planner": (PlannerNode, "rate", 250.0),
    "driver": (DriverNode, "diagnostics_period", 0.5),
    "terrain_mapper": (TerrainMapperNode, "publish_rate", 5.0),
    "navigator": (NavigatorNode, "speed", 0.05),
}


@pytest.fixture(scope="module")
def changed_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    tree = yaml.safe_load(SHIPPED.read_text(encoding="utf-8"))
    for node, (_, name, value) in CHANGES.items():
        tree[f"/**/{node}"]["ros__parameters"][name] = value
    tree[f"/**/{NODE_NAME}"]["ros__parameters"]["speed_limit"] = 1.5
    path = tmp_path_factory.mktemp("params") / "params.yaml"
    path.write_text(yaml.safe_dump(tree), encoding="utf-8")
    return path


@pytest.mark.parametrize("node", list(CHANGES))
def test_each_node_takes_the_file_under_a_namespace(node: str, changed_file: Path) -> None:
    factory, name, value = CHANGES[node]
    rclpy.init(args=["--ros-args", "--params-file", str(changed_file), "-r",
                     "__ns:=/crawler1"])
    made = None
    try:
        made = factory()
        assert made.get_namespace() == "/crawler1"
        assert made.get_parameter(name).value == value
    finally:
        if made is not None:
            made.destroy_node()
        rclpy.try_shutdown()


def test_the_seabed_simulator_takes_the_file(changed_file: Path) -> None:
    pytest.importorskip("mujoco")
    from crawler_motion.sim.seabed.node import SeabedSimNode

    rclpy.init(args=["--ros-args", "--params-file", str(changed_file), "-p",
                     f"can_port:={free_udp_port()}", "-p", "record_fps:=5.0"])
    made = None
    try:
        made = SeabedSimNode()
        assert made.get_parameter("record_fps").value == 5.0
        assert made.get_parameter("medium").value == "water"  # from the file
    finally:
        if made is not None:
            made.destroy_node()
        rclpy.try_shutdown()


def test_the_simulated_manager_takes_the_file(changed_file: Path) -> None:
    shipped = manager_flags(parse_ros_args(["--ros-args", "--params-file", str(SHIPPED)],
                                           NODE_NAME))
    assert shipped[shipped.index("--speed-limit") + 1] == "2.0"
    ros = parse_ros_args(["--ros-args", "--params-file", str(changed_file), "-r",
                          "__ns:=/crawler1"], NODE_NAME)
    flags = manager_flags(ros)
    assert flags[flags.index("--speed-limit") + 1] == "1.5"
