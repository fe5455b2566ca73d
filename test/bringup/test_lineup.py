"""The bring-up's lineup and checks, without starting anything."""

from __future__ import annotations

from pathlib import Path

import pytest

from crawler_motion.bringup.checks import check_output, check_port_free, check_world
from crawler_motion.bringup.lineup import (
    BACKGROUND_NICE,
    SIM_HEARTBEAT_TIMEOUT_PERIODS,
    BringUpOptions,
    check_namespace,
    check_params_file,
    lineup,
)
from crawler_motion.errors import ConfigError
from crawler_motion.testing.bus import BusSpec

SHIPPED_PARAMS = Path(__file__).resolve().parents[2] / "config" / "params.yaml"


def names(options: BringUpOptions) -> list[tuple[str, int, int]]:
    return [(m.name, m.stage, m.nice) for m in lineup(options)]


def test_sim_starts_the_simulator_then_the_controller_then_the_rest_nicer():
    assert names(BringUpOptions()) == [
        ("seabed_sim", 0, 0), ("controller_node", 1, 0),
        ("terrain_mapper", 2, BACKGROUND_NICE), ("navigator", 2, BACKGROUND_NICE)]
    assert BACKGROUND_NICE > 0


def test_split_runs_the_driver_and_the_planner_apart():
    members = {m.name: m for m in lineup(BringUpOptions(split=True))}
    assert [n for n in members] == ["seabed_sim", "driver_node", "planner_node",
                                    "terrain_mapper", "navigator"]
    assert members["driver_node"].nodes == ("driver",)
    assert members["planner_node"].nodes == ("planner",)


def test_up_has_no_simulator_and_record_and_view_join(tmp_path: Path):
    members = lineup(BringUpOptions(simulate=False, record=tmp_path / "run.mcap", view=True))
    assert [m.name for m in members] == ["controller_node", "terrain_mapper", "navigator",
                                         "recorder", "view"]
    assert str(tmp_path / "run.mcap") in members[3].command
    assert {m.name: m.nice for m in members} == {
        "controller_node": 0, "terrain_mapper": BACKGROUND_NICE, "navigator": BACKGROUND_NICE,
        "recorder": BACKGROUND_NICE, "view": BACKGROUND_NICE}


def test_every_node_gets_the_file_the_namespace_and_the_bus(tmp_path: Path):
    bus = BusSpec("udp_multicast", "239.1.2.3", 12345)
    options = BringUpOptions(params=SHIPPED_PARAMS, namespace="/crawler1", bus=bus,
                             world="wall", medium="land")
    for member in lineup(options):
        cmd = list(member.command)
        assert cmd[cmd.index("--params-file") + 1] == str(SHIPPED_PARAMS), member.name
        assert "__ns:=/crawler1" in cmd, member.name
        # the overrides follow the file (ROS applies them after it)
        assert all(cmd.index("--params-file") < i for i, a in enumerate(cmd) if a == "-p")
    sim, controller = lineup(options)[:2]
    assert {"can_port:=12345", "world:=wall", "medium:=land"} <= set(sim.command)
    assert {"can_port:=12345", "autostart:=true"} <= set(controller.command)
    # the simulated manager's heartbeat tolerance, on the simulator only
    assert f"heartbeat_timeout_periods:={SIM_HEARTBEAT_TIMEOUT_PERIODS}" in controller.command
    real = lineup(BringUpOptions(simulate=False, bus=options.bus))
    assert not any("heartbeat_timeout_periods" in a for m in real for a in m.command)


@pytest.mark.parametrize("namespace, result", [
    ("", ""), ("/", ""), ("crawler1", "/crawler1"), ("/crawler1", "/crawler1"),
    ("/a/b_c", "/a/b_c"),
])
def test_valid_namespaces(namespace: str, result: str):
    assert check_namespace(namespace) == result


@pytest.mark.parametrize("namespace", ["1bad", "/a//b", "/a b", "/a-b", "/a/", "/ä", "/a__b"])
def test_invalid_namespaces_are_refused_with_the_rule(namespace: str):
    with pytest.raises(ConfigError, match="not a valid ROS namespace"):
        check_namespace(namespace)


@pytest.mark.parametrize("text, reason", [
    ("[1, 2", "not valid YAML"), ("- a\n- b\n", "not a ROS parameter file"),
    ("planner: {rate: 1}\n", "not a ROS parameter file"),
])
def test_bad_params_files_are_refused(tmp_path: Path, text: str, reason: str):
    path = tmp_path / "p.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=reason):
        check_params_file(path)


def test_missing_params_file_and_the_shipped_one(tmp_path: Path):
    with pytest.raises(ConfigError, match="cannot read"):
        check_params_file(tmp_path / "none.yaml")
    assert "/**/planner" in check_params_file(SHIPPED_PARAMS)


def test_world_and_output_checks(tmp_path: Path):
    check_world("wall")
    with pytest.raises(ConfigError, match=r"unknown world 'nope'.*flat"):
        check_world("nope")
    with pytest.raises(ConfigError, match="does not exist"):
        check_output(tmp_path / "no" / "run.mcap", "recording")
    with pytest.raises(ConfigError, match="is a directory"):
        check_output(tmp_path, "recording")


def test_a_port_in_use_is_named():
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        with pytest.raises(ConfigError, match=f"port {port} on 127.0.0.1 in use"):
            check_port_free("127.0.0.1", port, "Foxglove view")
