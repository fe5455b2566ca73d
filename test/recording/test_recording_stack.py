"""A short run of the stack (seabed simulator, driver, planner) recorded, logged, reported and
watched live: the MCAP read back with ``mcap``'s own reader, the CAN log replayed and decoded
with the DBC, the report's files, a damaged recording, and a WebSocket client on the view."""

from __future__ import annotations

import asyncio
import json
import random
import re
import socket
import time
from collections.abc import Iterator
from itertools import pairwise
from pathlib import Path
from typing import Any

import pytest
import yaml

can = pytest.importorskip("can")
rclpy = pytest.importorskip("rclpy")
websockets = pytest.importorskip("websockets")

from mcap.reader import make_reader  # noqa: E402
from mcap_ros2.decoder import DecoderFactory  # noqa: E402
from rclpy.serialization import deserialize_message  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from crawler_motion.canbus.protocol import MotorProtocol  # noqa: E402
from crawler_motion.errors import ProtocolError  # noqa: E402
from crawler_motion.model.config import load_config  # noqa: E402
from crawler_motion.recording import report  # noqa: E402
from crawler_motion.recording.launch import cli_command, record_command  # noqa: E402
from crawler_motion.recording.reader import read_recording  # noqa: E402
from crawler_motion.testing.bus import BusSpec  # noqa: E402
from crawler_motion.testing.stack import (  # noqa: E402
    StackProcesses,
    StackSpec,
    isolated_env,
)
from crawler_motion.tools.console import Console  # noqa: E402

CFG = load_config()
#: Topics the stack publishes during a stand and a walk (the console adds gait_command).
EXPECTED = {"/planner_status", "/driver_status", "/gait_command", "/joint_commands",
            "/joint_states", "/diagnostics", "/odom", "/imu", "/scan"}
VIEW_CHANNELS = {"/tf", "/odom", "/joint_states", "/robot_description", "/terrain_map", "/scan",
                 "/planner_status"}
COMMANDS = ({"command": "stand"}, {"command": "walk", "steps": 1})


def _free_tcp_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


async def _watch(url: str, topics: set[str], seconds: float) -> dict[str, Any]:
    """Connect to the view, subscribe to ``topics`` and collect what arrives."""
    got: dict[str, Any] = {"channels": {}, "messages": {}}
    async with websockets.connect(url, subprotocols=["foxglove.sdk.v1"]) as ws:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline and len(got["messages"]) < len(topics):
            try:
                frame = await asyncio.wait_for(ws.recv(), 1.0)
            except asyncio.TimeoutError:
                continue
            if isinstance(frame, str):
                op = json.loads(frame)
                if op["op"] == "advertise":
                    new = {c["id"]: c for c in op["channels"]}
                    got["channels"].update(new)
                    subs = [{"id": cid, "channelId": cid} for cid, c in new.items()
                            if c["topic"] in topics]
                    await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
            elif frame[0] == 1:  # message data: op, subscription id, log time, payload
                sub = int.from_bytes(frame[1:5], "little")
                got["messages"].setdefault(got["channels"][sub]["topic"], frame[13:])
    return got


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    out = tmp_path_factory.mktemp("recording")
    bus = BusSpec.fresh()
    domain = random.randint(102, 200)
    port = _free_tcp_port()
    spec = StackSpec(bus, rate=100.0, seabed={"world": "flat"})
    cli = cli_command()
    record = record_command(out / "run.mcap", bus, out / "run.log", quiet=False)
    procs = StackProcesses(out)
    procs.start({"recorder": record, "killed": [*cli, "record", "-o", str(out / "killed.mcap"),
                                                "--topics", "joint_states"],
                 "view": [*cli, "view", "--port", str(port)], **spec.commands()},
                isolated_env(domain))
    rclpy.init(domain_id=domain)
    console = Console("recording_console")
    console.printer = lambda _line: None
    try:
        assert console.connect(40.0), f"no planner{procs.died()}\n{procs.log_tails(8)}"
        # the recorder subscribes to a topic once it sees its publisher: wait for it
        assert console.wait_until(lambda: console.pub_cmd.get_subscription_count() >= 2, 10.0)
        for command in COMMANDS:
            ok, message = console.run_when_ready(dict(command), 40.0)
            assert ok, message
        watched = asyncio.run(_watch(f"ws://127.0.0.1:{port}", VIEW_CHANNELS, 10.0))
        procs.kill("killed")
        procs.stop(["recorder"])
        yield {"dir": out, "mcap": out / "run.mcap", "log": out / "run.log",
               "killed": out / "killed.mcap", "view": watched,
               "recorder_log": procs.tail("recorder", 5)}
    finally:
        console.close()
        rclpy.try_shutdown()
        procs.stop()


def _read(path: Path) -> dict[str, list[tuple[Any, Any, Any]]]:
    """Topic -> [(schema, message, decoded)] with mcap's own (indexed) reader."""
    topics: dict[str, list[tuple[Any, Any, Any]]] = {}
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            topics.setdefault(channel.topic, []).append((schema, message, decoded))
    return topics


def test_every_topic_is_recorded_with_its_schema_and_plausible_counts(run: dict) -> None:
    topics = _read(run["mcap"])
    assert EXPECTED <= set(topics), f"missing {EXPECTED - set(topics)}"
    assert topics["/joint_states"][0][0].name == "sensor_msgs/msg/JointState"
    assert topics["/joint_states"][0][0].encoding == "ros2msg"
    span = {t: (m[-1][1].log_time - m[0][1].log_time) * 1e-9 for t, m in topics.items()}
    # the planner ticks at 100 Hz while it moves; the driver reports every feedback cycle
    assert 30.0 < len(topics["/joint_commands"]) / span["/joint_commands"] < 130.0
    assert len(topics["/joint_states"]) / span["/joint_states"] > 20.0
    assert "killed" not in run["recorder_log"][-1] and "messages" in run["recorder_log"][-1]


def test_every_channel_carries_the_offered_qos_like_ros2_bag(run: dict) -> None:
    with open(run["mcap"], "rb") as stream:
        summary = make_reader(stream).get_summary()
    channels = {c.topic: c for c in summary.channels.values()}
    for topic, durability in (("/planner_status", "transient_local"),
                              ("/driver_status", "transient_local"),
                              ("/joint_states", "volatile"), ("/odom", "volatile")):
        profiles = yaml.safe_load(channels[topic].metadata["offered_qos_profiles"])
        assert {(p["reliability"], p["durability"]) for p in profiles} \
            == {("reliable", durability)}, topic


def test_stamps_are_plausible_and_cdr_decodes_to_the_published_values(run: dict) -> None:
    topics = _read(run["mcap"])
    for topic in ("/joint_states", "/joint_commands"):
        stamps = [d.header.stamp.sec + 1e-9 * d.header.stamp.nanosec for _, _, d in
                  topics[topic]]
        logged = [m.log_time * 1e-9 for _, m, _ in topics[topic]]
        assert all(b >= a for a, b in pairwise(logged))
        assert max(abs(s - t) for s, t in zip(stamps, logged, strict=True)) < 1.0, topic
        assert list(topics[topic][-1][2].name) == list(CFG.robot.joint_names)
    sent = [json.loads(d.data) for _, _, d in topics["/gait_command"]]
    # the console repeats a command until the planner takes it
    assert [c for i, c in enumerate(sent) if not i or c != sent[i - 1]] == list(COMMANDS)


def test_a_killed_recording_keeps_its_closed_chunks(run: dict) -> None:
    rec = read_recording(run["killed"])
    assert rec.damage is not None and "killed.mcap" in rec.damage
    assert len(rec.topic("joint_states")) > 100 and set(rec.messages) == {"/joint_states"}


def test_the_can_log_replays_and_decodes_with_the_dbc(run: dict) -> None:
    protocol = MotorProtocol.from_config(CFG.robot)
    kinds: dict[str, int] = {}
    undecodable = 0
    for msg in can.LogReader(str(run["log"])):
        try:
            kind = type(protocol.decode(msg)).__name__
        except ProtocolError:
            undecodable += 1
            continue
        kinds[kind] = kinds.get(kind, 0) + 1
    assert kinds.get("TargetFrame", 0) > 100, kinds  # driver -> manager
    assert sum(kinds.values()) - kinds.get("TargetFrame", 0) > 100, kinds  # and back
    assert undecodable == 0


def test_the_report_writes_its_pictures_and_the_index_shows_them(run: dict) -> None:
    out = run["dir"] / "report"
    assert report.main([str(run["mcap"]), "-o", str(out)]) == 0
    page = (out / "index.html").read_text()
    pictures = re.findall(r'<img src="([^"]+)"', page)
    assert {"joints.png", "tracking_error.png", "feet.png", "path.png", "states.png"} \
        <= set(pictures)
    for name in pictures:
        assert (out / name).stat().st_size > 1000
    assert "largest tracking error" in page and "body displacement" in page


def test_a_truncated_recording_gives_one_line_and_a_partial_report(run: dict, tmp_path: Path,
                                                                   capsys: Any) -> None:
    data = run["mcap"].read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:len(data) // 2])
    assert report.main([str(cut), "-o", str(tmp_path / "r")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cut.mcap" in err[0] and "Traceback" not in err[0]
    assert (tmp_path / "r" / "index.html").is_file()


def test_the_live_view_advertises_its_channels_and_sends_messages(run: dict) -> None:
    view = run["view"]
    topics = {c["topic"] for c in view["channels"].values()}
    assert VIEW_CHANNELS <= topics
    assert {"/tf", "/joint_states", "/robot_description"} <= set(view["messages"])
    state = deserialize_message(bytes(view["messages"]["/joint_states"]), JointState)
    assert list(state.name) == list(CFG.robot.joint_names)
