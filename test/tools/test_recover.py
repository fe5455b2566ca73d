"""``console recover`` / ``console status``: the options and the causes recover refuses on."""

from __future__ import annotations

import pytest

from crawler_motion.tools.console import build_parser
from crawler_motion.tools.recover import PERSISTENT_CAUSES, persistent_cause


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
