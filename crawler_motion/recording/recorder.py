"""``crawler-motion record`` and the ``recorder`` node: the running stack into a ROS 2 MCAP file.

Like ``ros2 bag record``: every topic on the graph (or the ``--topics`` given) is recorded, its
serialised CDR messages unchanged under their ``ros2msg`` schemas, each channel with the
``offered_qos_profiles`` of its publishers. The stack's own topics are subscribed to at start
with the QoS their publishers declare (`crawler_motion.recording.qos`), so nothing they publish
after the recorder started is lost; other topics as soon as the graph poll sees a publisher,
with the publishers' QoS. A topic that appears late is picked up when it appears; one that never
appears is simply absent. Messages the recorder could not keep up with (its queue overflowed)
are counted from the publishers' sequence numbers (`gaps`) and reported on the progress line
and at the end. The output file (and the CAN log) is opened before anything is
subscribed: an unwritable path is one line on stderr and exit status 1.
"""

from __future__ import annotations

import argparse
import importlib
import signal
import sys
import time
from collections.abc import Sequence
from functools import partial
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.subscription import Subscription

from crawler_motion.canbus.bus import UDP_MULTICAST, default_channel
from crawler_motion.errors import CrawlerMotionError
from crawler_motion.recording.can_log import CanLog
from crawler_motion.recording.gaps import SequenceGaps
from crawler_motion.recording.qos import (
    Qos,
    adapted_qos,
    compatible,
    declared_qos,
    offered_qos_profiles,
    requested_qos,
)
from crawler_motion.recording.recovery import recover
from crawler_motion.recording.sink import McapSink
from crawler_motion.recording.topics import STACK_TOPICS, absolute
from crawler_motion.runtime.cli_args import OneLineParser, finite_number

PROG = "crawler-motion record"
#: Topics of the ROS infrastructure, not recorded unless named in ``--topics``.
INFRASTRUCTURE = frozenset({"/rosout", "/parameter_events"})
#: Graph polling period [s] and progress line period [s].
DISCOVERY_PERIOD = 0.5
PROGRESS_PERIOD = 1.0


def message_class(type_name: str) -> Any:
    """The Python class of ``pkg/msg/Type``."""
    package, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


class RecorderNode(Node):
    """Subscribes (raw) to the wanted topics and writes them to ``sink``: the stack's own topics
    at once with the QoS their publishers declare, every other topic as it appears."""

    def __init__(self, sink: McapSink, topics: Sequence[str] | None = None,
                 context: Context | None = None) -> None:
        super().__init__("recorder", context=context)
        self.sink = sink
        self.wanted = None if not topics else {absolute(t) for t in topics}
        self.subscribed: dict[str, str] = {}
        self.requested: dict[str, Qos] = {}
        self.skipped: set[str] = set()
        self.gaps = SequenceGaps()
        self._recording_subs: dict[str, Subscription] = {}
        self._known = {absolute(t): t for t in STACK_TOPICS}
        for name, topic in self._known.items():
            if self.wanted is None or name in self.wanted:
                self._subscribe(name, STACK_TOPICS[topic], requested_qos([declared_qos(topic)]))
        self.create_timer(DISCOVERY_PERIOD, self.discover)
        self.discover()

    def _subscribe(self, name: str, type_name: str, qos: Qos) -> None:
        """(Re-)subscribe to ``name`` as ``type_name`` with ``qos``."""
        cls = message_class(type_name)
        old = self._recording_subs.pop(name, None)
        if old is not None:
            self.destroy_subscription(old)
        self._recording_subs[name] = self.create_subscription(
            cls, name, partial(self.on_message, name, type_name), ros_qos(qos), raw=True)
        self.subscribed[name] = type_name
        self.requested[name] = qos

    def discover(self) -> None:
        """Subscribe to every wanted topic that has publishers now; re-subscribe a known topic
        whose publishers offer another type or a QoS the subscription does not match."""
        for name, types in self.get_topic_names_and_types():
            if name in self.skipped:
                continue
            if (name not in self.wanted) if self.wanted is not None else name in INFRASTRUCTURE:
                continue
            publishers = self.get_publishers_info_by_topic(name)
            if not publishers:
                continue
            if name in self.subscribed:
                self._adapt(name, types, publishers)
                continue
            try:
                self._subscribe(name, types[0], adapted_qos(publishers))
            except (ImportError, AttributeError, ValueError):
                self.get_logger().warning(f"{name}: type {types[0]} not installed; not recorded")
                self.skipped.add(name)

    def _adapt(self, name: str, types: Sequence[str], publishers: Sequence[Any]) -> None:
        """Follow the graph when the publishers of a subscribed topic do not match it."""
        if self.subscribed[name] not in types:
            if self.sink.has_channel(name):
                self.get_logger().warning(f"{name}: published as {', '.join(types)}, recorded "
                                          f"as {self.subscribed[name]}; other types not recorded")
                self.skipped.add(name)
                return
            self.get_logger().info(f"{name}: published as {types[0]}, not "
                                   f"{self.subscribed[name]}: re-subscribed")
            self._subscribe(name, types[0], adapted_qos(publishers))
        elif not all(compatible(self.requested[name], p.qos_profile) for p in publishers):
            qos = adapted_qos(publishers)
            self.get_logger().info(f"{name}: a publisher offers less than "
                                   f"{qos_text(self.requested[name])}: re-subscribed "
                                   f"{qos_text(qos)}")
            self._subscribe(name, self.subscribed[name], qos)

    def offered(self, name: str) -> list[Any]:
        """The QoS the publishers of ``name`` offer; without publishers on the graph (gone
        already), what the stack's publisher declares or else what was requested."""
        profiles = [p.qos_profile for p in self.get_publishers_info_by_topic(name)]
        if profiles:
            return profiles
        return [declared_qos(self._known[name]) if name in self._known
                else self.requested[name]]

    def on_message(self, topic: str, type_name: str, data: bytes, info: dict[str, Any]
                   ) -> None:
        """Write one serialised message, stamped with its reception time; count the messages
        of its publisher missed before it (``info``: rclpy's message info)."""
        self.gaps.note(topic, info.get("publication_sequence_number"))
        if not self.sink.has_channel(topic):
            self.sink.channel(topic, type_name,
                              {"offered_qos_profiles": offered_qos_profiles(self.offered(topic))})
        self.sink.write(topic, type_name, data, time.time_ns())

    def missing(self) -> list[str]:
        """Wanted topics never recorded."""
        return sorted(t for t in (self.wanted or set()) if not self.sink.has_channel(t))


def qos_text(qos: Qos) -> str:
    """``reliable/transient_local`` and the like."""
    return f"{qos.reliability}/{qos.durability}"


def ros_qos(qos: Qos) -> QoSProfile:
    """The rclpy profile of ``qos`` (keep last ``depth``)."""
    return QoSProfile(depth=qos.depth, reliability=ReliabilityPolicy[qos.reliability.upper()],
                      durability=DurabilityPolicy[qos.durability.upper()])


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """The recorder's options."""
    parser = OneLineParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", default=None, help="MCAP file to write (required "
                        "unless --recover; with it default <stem>.recovered.mcap)")
    parser.add_argument("--recover", default=None, metavar="FILE",
                        help="record nothing: copy the readable messages of FILE, a recording "
                        "cut by a kill or a power loss, into a complete MCAP file (-o)")
    parser.add_argument("--topics", nargs="+", default=None,
                        help="topics to record (default: every topic on the graph)")
    parser.add_argument("--duration", type=finite_number("--duration", positive=True),
                        default=None, help="stop after [s] (default: at Ctrl-C)")
    parser.add_argument("--can-log", default=None,
                        help="also log the CAN bus to this .log (candump) / .asc / .blf file")
    parser.add_argument("--interface", default=UDP_MULTICAST, help="CAN interface of --can-log")
    parser.add_argument("--channel", default=None, help="CAN channel (default per interface)")
    parser.add_argument("--port", type=int, default=0, help="udp_multicast port (0: default)")
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    args, _ros = parser.parse_known_args(argv)
    if args.output is None and args.recover is None:
        parser.error("the following arguments are required: -o/--output")
    return args


def recover_main(source: str, output: str | None) -> int:
    """``--recover``: the complete copy of a cut recording; its line, or the error."""
    try:
        result = recover(source, output)
    except CrawlerMotionError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    cut = f"; cut at: {result.damage}" if result.damage else "; the file was intact"
    print(f"recovered {result.messages} messages into {result.output}{cut}")
    return 0


def progress(sink: McapSink, elapsed: float, can_log: CanLog | None,
             gaps: SequenceGaps | None = None) -> str:
    """The progress line: duration, messages, MB (dropped messages, CAN frames)."""
    line = (f"recording {sink.path}: {elapsed:7.1f} s, {sink.messages:8d} messages, "
            f"{sink.size() / 1e6:7.2f} MB")
    if gaps is not None and gaps.total:
        line += f", {gaps.total} dropped"
    return line + (f", {can_log.counter.frames} CAN frames" if can_log else "")


def _spin(node: RecorderNode, duration: float | None, quiet: bool,
          can_log: CanLog | None) -> None:
    """Spin until ``duration`` [s] has passed or Ctrl-C, printing the progress line."""
    start = last = time.monotonic()
    while rclpy.ok() and (duration is None or time.monotonic() - start < duration):
        rclpy.spin_once(node, timeout_sec=0.1)
        if not quiet and time.monotonic() - last >= PROGRESS_PERIOD:
            last = time.monotonic()
            print("\r" + progress(node.sink, last - start, can_log, node.gaps), end="",
                  file=sys.stderr, flush=True)


def _open(args: argparse.Namespace) -> tuple[McapSink, CanLog | None]:
    """The output file and the CAN log, opened before any subscription."""
    sink = McapSink(args.output)
    try:
        channel = args.channel or default_channel(args.interface) or ""
        can_log = CanLog(args.can_log, args.interface, channel, args.port) \
            if args.can_log else None
    except CrawlerMotionError:
        sink.close()
        sink.path.unlink(missing_ok=True)  # nothing half-made stays behind
        raise
    return sink, can_log


def main(argv: Sequence[str] | None = None) -> int:
    """Record until ``--duration`` or Ctrl-C / SIGTERM; returns the exit status."""
    args = parse_args(sys.argv[1:] if argv is None else argv)
    if args.recover is not None:
        return recover_main(args.recover, args.output)
    try:
        sink, can_log = _open(args)
    except CrawlerMotionError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    signal.signal(signal.SIGTERM, signal.default_int_handler)
    rclpy.init(args=None)
    node = None
    status = 0
    start = time.monotonic()
    try:
        node = RecorderNode(sink, args.topics)
        _spin(node, args.duration, args.quiet, can_log)
    except KeyboardInterrupt:
        pass
    except CrawlerMotionError as exc:
        print(f"\n{PROG}: error: {exc}", file=sys.stderr)
        status = 1
    finally:
        status = _close(sink, can_log, node) or status
        if not args.quiet:  # the last line, also after Ctrl-C / SIGTERM (and rclpy's warnings)
            print("\r" + progress(sink, time.monotonic() - start, can_log,
                                  node.gaps if node else None), file=sys.stderr)
    return status


def _close(sink: McapSink, can_log: CanLog | None, node: RecorderNode | None) -> int:
    """Finish the file and the log, report topics never seen; 1 when finishing failed."""
    status = 0
    try:
        sink.close()
    except CrawlerMotionError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        status = 1
    if can_log is not None:
        can_log.close()
    if node is not None:
        if node.missing():
            print(f"{PROG}: never published: {', '.join(node.missing())}", file=sys.stderr)
        if node.gaps.total:
            worst = ", ".join(f"{t} {n}" for t, n in node.gaps.dropped.most_common(5) if n)
            print(f"{PROG}: {node.gaps.total} messages dropped (not kept up with): {worst}",
                  file=sys.stderr)
        node.destroy_node()
    rclpy.try_shutdown()
    return status


def node_main() -> None:
    """The ``recorder`` console script (same options; ``--ros-args`` are passed to ROS)."""
    sys.exit(main())


if __name__ == "__main__":
    sys.exit(main())
