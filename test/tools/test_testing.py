"""The shared stack launcher and bus tap (crawler_motion.testing), without ROS."""

from __future__ import annotations

import socket
import subprocess
import sys
import time
import uuid

import can
import pytest

from crawler_motion.canbus.protocol import MotorProtocol
from crawler_motion.model.config import load_config
from crawler_motion.testing.bus import (
    DEFAULT_GROUP,
    BusSpec,
    free_udp_port,
    random_multicast_group,
)
from crawler_motion.testing.stack import (
    EXECUTABLES,
    StackProcesses,
    StackSpec,
    isolated_env,
    node_command,
    random_domain,
    ros_args,
    ros_value,
)
from crawler_motion.testing.tap import (
    FAMILIES,
    BusTap,
    FamilyCounter,
    FrameRecorder,
    frame_families,
)

PROTOCOL = MotorProtocol.from_config(load_config().robot)


def test_free_udp_port_says_when_every_draw_is_held(monkeypatch):
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as held:
        held.bind(("", 0))
        port = held.getsockname()[1]
        monkeypatch.setattr("crawler_motion.testing.bus.random.randint", lambda *_: port)
        with pytest.raises(OSError, match=r"no free UDP port .* after 3 draws"):
            free_udp_port(attempts=3)


def test_default_group_is_python_can_s():
    from can.interfaces.udp_multicast import UdpMulticastBus

    assert DEFAULT_GROUP == UdpMulticastBus.DEFAULT_GROUP_IPv4


def test_free_udp_port_and_random_group():
    for _ in range(20):  # never a port DDS or the kernel may bind after it is drawn
        port = free_udp_port()
        assert 1024 <= port < 7400
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.bind(("", port))
    for _ in range(50):
        octets = [int(x) for x in random_multicast_group().split(".")]
        assert octets[0] == 239 and all(1 <= x <= 254 for x in octets[1:])


@pytest.mark.parametrize(("interface", "channel", "cli", "params", "text"), [
    ("udp_multicast", None, ["--interface", "udp_multicast", "--channel", DEFAULT_GROUP,
                             "--port", "{port}"],
     {"can_interface": "udp_multicast", "can_channel": DEFAULT_GROUP, "can_port": "{port}"},
     f"udp_multicast {DEFAULT_GROUP}:{{port}}"),
    ("udp_multicast", "239.1.2.3", ["--interface", "udp_multicast", "--channel", "239.1.2.3",
                                    "--port", "{port}"],
     {"can_interface": "udp_multicast", "can_channel": "239.1.2.3", "can_port": "{port}"},
     "udp_multicast 239.1.2.3:{port}"),
    ("socketcan", None, ["--interface", "socketcan", "--channel", "vcan0"],
     {"can_interface": "socketcan", "can_channel": "vcan0"}, "socketcan vcan0"),
    ("socketcan", "vcan1", ["--interface", "socketcan", "--channel", "vcan1"],
     {"can_interface": "socketcan", "can_channel": "vcan1"}, "socketcan vcan1"),
])
def test_bus_spec(interface, channel, cli, params, text):
    bus = BusSpec.fresh(interface, channel)
    port = bus.port

    def fill(value):
        return port if value == "{port}" and isinstance(params.get("can_port"), str) else value

    assert bus.udp == (interface == "udp_multicast")
    assert (port > 0) == bus.udp
    assert bus.cli_args() == [str(port) if a == "{port}" else a for a in cli]
    assert bus.ros_params() == {k: port if v == "{port}" else v for k, v in params.items()}
    assert str(bus) == text.format(port=port)
    assert fill("x") == "x"


@pytest.mark.parametrize(("value", "text"), [
    (True, "true"), (False, "false"), (1.0, "1.0"), (100, "100"), (0, "0"), ("wave", "wave"),
])
def test_ros_value_keeps_the_type(value, text):
    assert ros_value(value) == text


def test_ros_args():
    assert ros_args({}) == ["--ros-args"]
    assert ros_args({"a": 1, "b": True}, ["__ns:=/x"]) == [
        "--ros-args", "-r", "__ns:=/x", "-p", "a:=1", "-p", "b:=true"]


def test_node_command_is_the_script_or_the_module():
    for name, module in EXECUTABLES.items():
        cmd = node_command(name)
        assert cmd[0].endswith(name) or cmd == [sys.executable, "-m", module]


def _params(cmd):
    return dict(cmd[i + 1].split(":=", 1) for i, a in enumerate(cmd) if a == "-p")


def test_stack_spec_commands():
    bus = BusSpec("udp_multicast", "239.1.2.3", 4242)
    spec = StackSpec(bus, rate=200, command_timeout=0.5, speed_limit=3,
                     driver={"diagnostics_period": 0.25}, planner={"gait": "wave"})
    cmds = spec.commands()
    assert list(cmds) == ["sim", "driver", "planner"]
    assert _params(cmds["sim"]) == {"can_interface": "udp_multicast", "can_channel": "239.1.2.3",
                                    "can_port": "4242", "speed_limit": "3.0"}
    assert _params(cmds["driver"]) == {
        "autostart": "true", "command_timeout": "0.5", "can_interface": "udp_multicast",
        "can_channel": "239.1.2.3", "can_port": "4242", "diagnostics_period": "0.25"}
    assert _params(cmds["planner"]) == {"rate": "200.0", "gait": "wave"}


def test_stack_spec_composed_controller_takes_both_parameter_sets():
    bus = BusSpec("udp_multicast", "239.1.2.3", 4242)
    cmds = StackSpec(bus, rate=500, driver={"priority": 0}, planner={"gait": "wave"},
                     remaps=("__ns:=/c1",), controller=True).commands()
    assert list(cmds) == ["sim", "controller"]
    command = node_command("controller_node")
    assert cmds["controller"][:len(command)] == command
    params = _params(cmds["controller"])
    assert params["rate"] == "500.0" and params["gait"] == "wave" and params["priority"] == "0"
    assert params["can_port"] == "4242" and params["autostart"] == "true"
    assert "__ns:=/c1" in cmds["controller"] and "__ns:=/c1" in cmds["sim"]


def test_stack_spec_without_sim_or_planner_and_with_remaps():
    spec = StackSpec(BusSpec.fresh(), sim=False, planner=None, remaps=("__ns:=/t",),
                     names={n: n for n in EXECUTABLES})
    cmds = spec.commands()
    assert list(cmds) == ["driver_node"]
    assert cmds["driver_node"][cmds["driver_node"].index("-r") + 1] == "__ns:=/t"


def test_isolated_env(monkeypatch):
    monkeypatch.setenv("ROS_DOMAIN_ID", "7")
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "SUBNET")
    assert isolated_env()["ROS_DOMAIN_ID"] == "7"
    env = isolated_env(150)
    assert env["ROS_DOMAIN_ID"] == "150"
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert all(1 <= random_domain() <= 101 for _ in range(100))


def test_stack_processes_log_stop_and_report(tmp_path):
    procs = StackProcesses(tmp_path)
    procs.start({"quick": [sys.executable, "-c", "print('one'); print('two')"],
                 "slow": [sys.executable, "-c", "import time; print('up', flush=True); "
                                                "time.sleep(60)"]}, isolated_env())
    procs.procs["quick"].wait(10)
    deadline = time.monotonic() + 10
    while "up" not in procs.tail("slow", 5) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert procs.died() == f" (quick exited 0; logs in {tmp_path})"
    assert procs.tail("quick", 1) == ["two"]
    assert procs.tail("missing", 1) == []
    assert procs.log_tails(2) == "--- quick ---\none\ntwo\n--- slow ---\nup"
    assert procs.log_tails(1, "{name} {path}").splitlines()[0] == f"quick {tmp_path}/quick.log"
    assert set(procs.pids()) == {"quick", "slow"}
    procs.stop(timeout=5)
    assert procs.procs["slow"].returncode is not None
    assert "slow exited" in procs.died()


def test_frame_families_cover_the_protocol():
    families = frame_families(PROTOCOL)
    assert set(families.values()) == set(FAMILIES[:-1])
    for kind in FAMILIES[:-1]:
        assert {fid for fid, k in families.items() if k == kind} == set(PROTOCOL.frame_ids(kind))


def test_tap_counts_and_records_frames_through_a_notifier():
    channel = f"tap-{uuid.uuid4().hex}"
    sender = can.Bus(interface="virtual", channel=channel)
    counter, recorder = FamilyCounter(PROTOCOL), FrameRecorder(lambda t: t + 1000.0)
    tap = BusTap(can.Bus(interface="virtual", channel=channel), [counter, recorder])
    try:
        frames = [*PROTOCOL.encode_targets((PROTOCOL.lower + PROTOCOL.upper) / 2, 1),
                  PROTOCOL.encode_control("enable"),
                  can.Message(arbitration_id=0x555, data=bytes(8), is_extended_id=False)]
        for msg in frames:
            sender.send(msg)
        deadline = time.monotonic() + 5
        while len(recorder.frames) < len(frames) and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        tap.stop()
        tap.stop()  # idempotent
        sender.shutdown()
    n_targets = len(PROTOCOL.frame_ids("target"))
    assert dict(counter.counts) == {"target": n_targets, "control": 1, "other": 1}
    assert [m.arbitration_id for _, m in recorder.frames] == [m.arbitration_id for m in frames]
    assert all(t == m.timestamp + 1000.0 for t, m in recorder.frames)
    assert counter.errors == 0


def test_a_listener_error_is_counted_and_the_tap_goes_on():
    class Boom(FamilyCounter):
        def on_message_received(self, msg):
            super().on_message_received(msg)
            if msg.arbitration_id == 0x555:
                raise ValueError("boom")

    channel = f"tap-{uuid.uuid4().hex}"
    sender = can.Bus(interface="virtual", channel=channel)
    boom = Boom(PROTOCOL)
    with BusTap(can.Bus(interface="virtual", channel=channel), [boom]):
        for arbitration_id in (0x555, 0x556):
            sender.send(can.Message(arbitration_id=arbitration_id, data=bytes(8),
                                    is_extended_id=False))
        deadline = time.monotonic() + 5
        while boom.counts["other"] < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
    sender.shutdown()
    assert boom.counts["other"] == 2 and boom.errors == 1


def test_netns_unavailable_says_why(monkeypatch):
    from crawler_motion.testing import netns

    monkeypatch.setattr(netns.shutil, "which", lambda _name: None)
    assert "`ip` command" in netns.netns_unavailable()
    monkeypatch.setattr(netns.shutil, "which", lambda _name: "/usr/sbin/ip")
    monkeypatch.setattr(netns, "_ip", lambda *args, check=True: subprocess.CompletedProcess(
        ["ip", *args], 1, "", "mount --make-shared /run/netns failed: Operation not permitted"))
    assert "Operation not permitted" in netns.netns_unavailable()
