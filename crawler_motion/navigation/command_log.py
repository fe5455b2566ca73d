"""The navigator's goals and follow commands, refused and taken: counted, logged, rate-limited."""

from __future__ import annotations

import re
from collections import Counter
from typing import Any

from crawler_motion.runtime.log import Severity, Throttle, log

#: Numbers in a refusal's text: one log line per kind of refusal, not per goal.
NUMBERS = re.compile(r"[-+]?\d[\d.e+-]*")


class CommandLog:
    """Counts refusals (``refusals``, ``last_refusal``) and commands taken (``accepted`` by
    kind); logs each once a second per kind (a refusal's kind: its text with the numbers
    taken out, so a flood of different bad goals logs one line a second); says whether the
    status may go out (at most every ``status_period`` [s]: a flood floods neither)."""

    def __init__(self, logger: Any, status_period: float) -> None:
        self.logger = logger
        self.refusals, self.last_refusal = 0, ""
        self.accepted: Counter[str] = Counter()
        self._log, self._status = Throttle(1.0), Throttle(status_period)

    def refused(self, why: str) -> bool:
        """Count and log a refusal; True when the status may be published now."""
        self.refusals, self.last_refusal = self.refusals + 1, why
        if self._log.allow(NUMBERS.sub("#", why)):
            log(self.logger, Severity.WARNING, f"goal refused: {why} ({self.refusals} so far)")
        return self._status.allow("status")

    def taken(self, kind: str, text: str) -> bool:
        """Count and log a command of ``kind`` taken; True when the status may go out now."""
        self.accepted[kind] += 1
        if self._log.allow(kind):
            log(self.logger, Severity.INFO, f"{text} ({self.accepted[kind]} taken so far)")
        return self._status.allow("status")
