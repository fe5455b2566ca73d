"""Workarounds of documented rclpy behaviours, each in one small function naming its reference."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from lifecycle_msgs.srv import ChangeState
from rclpy.context import Context
from rclpy.lifecycle import LifecycleNode
from rclpy.publisher import Publisher


def guard_change_state(node: LifecycleNode, on_refused: Callable[[str], None]) -> None:
    """Answer an invalid ``change_state`` request with success=False instead of crashing.

    rclpy Jazzy raises RCLError (a RuntimeError) from the change_state service for a transition
    that is not valid in the current state, which ends ``rclpy.spin`` and with it the process
    (ros2/rclpy#1209, fixed upstream by ros2/rclpy#1319). rclpy offers no public hook, so this
    wraps the callback of the node's change_state service; no-op if the service is absent.
    """
    service = getattr(node, "_service_change_state", None)
    if service is None:
        return
    handler = service.callback

    def guarded(request: ChangeState.Request,
                response: ChangeState.Response) -> ChangeState.Response:
        try:
            return handler(request, response)
        except RuntimeError as exc:
            on_refused(f"change_state refused (transition {request.transition.id} "
                       f"{request.transition.label!r}): {exc}")
            response.success = False
            return response

    service.callback = guarded


def publish_unless_shut_down(publisher: Publisher, make: Callable[[], Any],
                             context: Context) -> Any:
    """Publish the message ``make()`` builds, from a thread other than the executor's, and
    return it; nothing once shutting down (the message is not even built then: None).

    A shutdown (Ctrl-C) may invalidate the context between the check and the publish; rclpy
    then raises RCLError (a RuntimeError) "publisher's context is invalid" (the shutdown race
    of ros2/rclcpp#812; rclpy's form reported in ros-visualization/interactive_markers#88).
    That error is ignored while shutting down and raised otherwise.
    """
    if not context.ok():
        return None
    msg = make()
    try:
        publisher.publish(msg)
    except RuntimeError:
        if context.ok():
            raise
        return None
    return msg
