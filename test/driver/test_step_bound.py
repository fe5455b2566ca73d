"""The driver's step bound and the malformed-frame rule (pure)."""

from __future__ import annotations

import can
import numpy as np
import pytest

from crawler_motion.driver.link import is_malformed_frame
from crawler_motion.driver.step_bound import StepBound

Q = np.zeros(12)
SPEED, MARGIN, PERIOD, TIMEOUT = 10.0, 0.05, 0.01, 0.2


@pytest.mark.parametrize("step, elapsed, refused", [
    (0.0, 0.01, False),
    (SPEED * 0.01 + MARGIN - 1e-9, 0.01, False),  # boundary: just inside
    (SPEED * 0.01 + MARGIN + 1e-6, 0.01, True),  # just beyond
    (SPEED * 0.01 + MARGIN, 0.001, False),  # bunched arrival: at least one period
    (SPEED * 0.1 + MARGIN - 1e-9, 0.1, False),
    (SPEED * TIMEOUT + MARGIN + 1e-6, 5.0, True),  # a long gap counts as the watchdog time
    (1.0, 0.01, True),  # the 1 rad step of the issue
])
def test_step_from_the_last_sent_target(step, elapsed, refused):
    bound = StepBound(PERIOD)
    bound.sent(Q, 1.0)
    q = Q.copy()
    q[7] = -step
    why = bound.check(q, np.full(12, np.nan), 1.0 + elapsed, SPEED, MARGIN, TIMEOUT)
    assert bool(why) == refused
    if refused:
        assert "joint 7" in why and "last sent target" in why


def test_after_enable_the_step_is_bounded_from_the_measured_pose():
    bound = StepBound(PERIOD)
    bound.sent(Q + 0.5, 1.0)
    bound.forget()
    measured = Q + 0.2
    assert bound.check(Q + 0.5, measured, 2.0, SPEED, MARGIN, TIMEOUT).count("measured pose")
    assert bound.check(measured + 0.1, measured, 2.0, SPEED, MARGIN, TIMEOUT) == ""
    assert "no measured pose" in bound.check(Q, np.full(12, np.nan), 2.0, SPEED, MARGIN,
                                             TIMEOUT)


def _raised(cause: BaseException | None) -> can.CanOperationError:
    try:
        try:
            if cause is not None:
                raise cause
            raise can.CanOperationError("could not unpack received message")
        except can.CanOperationError:
            raise
        except Exception as exc:
            raise can.CanOperationError("could not unpack received message") from exc
    except can.CanOperationError as exc:
        return exc


@pytest.mark.parametrize("exc, malformed", [
    (_raised(ValueError("unpack(b) received extra data")), True),  # udp_multicast bad datagram
    (_raised(KeyError("arbitration_id")), True),
    (_raised(OSError(9, "Bad file descriptor")), False),  # the socket is gone
    (_raised(None), False),  # no cause: taken as a transport error
    (OSError(100, "Network is down"), False),
    (can.CanError("bus off"), False),
])
def test_only_a_decoding_error_is_a_malformed_frame(exc, malformed):
    assert is_malformed_frame(exc) is malformed
