"""``console recover`` / ``console status``: the options and the causes recover refuses on."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from crawler_motion.tools.console import build_parser
from crawler_motion.tools.recover import PERSISTENT_CAUSES, persistent_cause, recover


@pytest.mark.parametrize("message, cause", [
    ("enabled, forwarding joint_commands", ""),
    ("ESTOP latched (~/estop service): ~/reset then ~/enable", ""),  # reset cures it
    ("command watchdog tripped (hold sent): call ~/enable", ""),  # enable cures it
    ("motor manager in hold, which the driver did not command (a spoofed frame or another "
     "controller): call ~/enable", ""),
    ("CAN bus down for 0.400 s", "the CAN bus is down"),
    ("heartbeat missing for 0.5 s (> 3 periods of 0.1 s)", "heartbeat is missing"),
    ("foreign control frame 0x080 (02fd) on the bus: another controller or an attacker",
     "foreign frames"),
    ("joint_commands from more than one publisher (interleaved sequence numbers)",
     "a second publisher"),
    ("stalled (not following the target): lf_knee_joint", "stalled"),
])
def test_persistent_causes(message, cause):
    found = persistent_cause(message)
    assert (cause in found) if cause else found == ""


def test_every_cause_is_named():
    assert all(text and why for text, why in PERSISTENT_CAUSES)


@pytest.mark.parametrize("argv", [["recover"], ["status", "--duration", "0.5"]])
def test_recover_and_status_parse(argv):
    assert build_parser().parse_args(argv).action == argv[0]


class ScriptedDriver:
    """`DriverState` without ROS: an active, enabled driver whose manager diagnostic is the
    next message of a script at each spin (`ScriptedConsole`)."""

    def __init__(self, messages: list[str]) -> None:
        self.status = {"lifecycle": "active", "state": "enabled"}
        self.state = "enabled"
        self._messages = iter(messages)
        self.manager: tuple[int, str, dict[str, str]] | None = None
        self.advance()

    def advance(self) -> None:
        message = next(self._messages, None)
        if message is not None:
            self.manager = (2 if persistent_cause(message) else 0, message,
                            {"manager_state": "enabled"})

    def manager_state(self) -> str:
        return "enabled"


class ScriptedConsole:
    def __init__(self, driver: ScriptedDriver) -> None:
        self.status = {"state": "IDLE"}
        self.driver = driver

    def wait_until(self, predicate: Callable[[], bool], timeout: float) -> bool:
        for _ in range(5):  # five spins stand for the timeout
            if predicate():
                return True
            self.driver.advance()
        return predicate()


@pytest.mark.parametrize("messages, ok, words", [
    (["OK"], True, "recovered"),
    # the report of just before a restart, then the heartbeat seen: not a cause any more
    (["heartbeat missing for 0.5 s (> 3 periods of 0.1 s)", "OK"], True, "recovered"),
    (["heartbeat missing for 0.5 s (> 3 periods of 0.1 s)"] * 9, False,
     "refused: the motor manager's heartbeat is missing: is it powered?"),
])
def test_recover_refuses_a_cause_only_while_it_stays(messages, ok, words):
    driver = ScriptedDriver(messages)
    result = recover(ScriptedConsole(driver), driver, lambda _line: None)  # type: ignore
    assert result[0] is ok and words in result[1], result
