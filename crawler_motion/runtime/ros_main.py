"""The console-script `main` of every node: spin until Ctrl-C or shutdown (demo_nodes_py);
several nodes in one process (`run_nodes`) for the composed controller."""

from __future__ import annotations

import gc
import sys
from collections.abc import Callable, Sequence

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

from crawler_motion.errors import CrawlerMotionError
from crawler_motion.runtime.dds import dds_defaults

#: Errors of a node's construction that mean "bad parameters or files": one line, exit 1.
STARTUP_ERRORS: tuple[type[Exception], ...] = (CrawlerMotionError, ParameterException)


def run_node(make_node: Callable[[], Node], prefix: str, args: Sequence[str] | None = None,
             *, switch_interval: float | None = None) -> None:
    """Create the node with ``make_node`` and spin it until Ctrl-C or an external shutdown.

    A start-up error (`STARTUP_ERRORS`) prints ``<prefix>: <error>`` on stderr as one line and
    exits with status 1 after the node is destroyed. ``switch_interval`` [s]: the GIL switch
    interval for nodes whose real-time thread must not wait 5 ms for the executor.
    """
    run_nodes(lambda nodes: nodes.append(make_node()), prefix, args,
              switch_interval=switch_interval)


def run_nodes(make_nodes: Callable[[list[Node]], None], prefix: str,
              args: Sequence[str] | None = None, *,
              switch_interval: float | None = None) -> None:
    """`run_node` for several nodes in one process and one executor (ROS 2 composition):
    ``make_nodes(nodes)`` appends each node to ``nodes`` as soon as it is built, so those built
    before a start-up error are destroyed too (in reverse order, as at the end)."""
    if switch_interval is not None:
        sys.setswitchinterval(switch_interval)
    dds_defaults()
    rclpy.init(args=None if args is None else list(args))
    nodes: list[Node] = []
    failed = ""
    try:
        make_nodes(nodes)
        # what start-up built (rclpy, the DBC database, the models) lives as long as the
        # process: out of the collector's generations, a collection walks only what the loop
        # allocates (measured: the longest tick gap of the controller at 500 Hz 6.8-11.4 ->
        # 3.9-6.9 ms, docs/benchmarks.md)
        gc.collect()
        gc.freeze()
        executor = SingleThreadedExecutor()
        for node in nodes:
            executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RuntimeError:
        # a signal shuts the context down while the executor takes a message: rclpy raises
        # RuntimeError ("Unable to convert call argument '0' to Python object") from
        # take_message instead of ExternalShutdownException; a shutdown, not a failure
        if rclpy.ok():
            raise
    except STARTUP_ERRORS as exc:
        failed = f"{prefix}: {exc}"
    finally:
        for node in reversed(nodes):
            node.destroy_node()
        rclpy.try_shutdown()
    if failed:
        print(failed, file=sys.stderr)
        sys.exit(1)
