"""The DDS settings every process of the package starts with (set before ``rclpy.init``).

Fast DDS publishes synchronously by default: ``publish`` sends from the calling thread under the
writer's locks, and rclpy holds the GIL through the call. When a new participant joins (a node
starting, ``crawler-motion console``, a recorder, Foxglove) the writers' locks are taken by
discovery, and a ``publish`` then waited 0.2-0.4 s with the GIL held: every thread of the
process stopped with it (measured on the simulator: its manager thread sent no heartbeat for
0.33-0.45 s; in the driver, the CAN thread stopped for 0.29-0.37 s, longer than the manager's
0.2 s command timeout). With ``RMW_FASTRTPS_PUBLICATION_MODE=ASYNCHRONOUS`` (rmw_fastrtps'
documented switch) ``publish`` queues the sample and a DDS thread sends it. A value the user
set is kept.
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping

#: rmw_fastrtps' switch of the publication mode (SYNCHRONOUS, ASYNCHRONOUS, AUTO).
PUBLICATION_MODE_VAR = "RMW_FASTRTPS_PUBLICATION_MODE"
#: The mode our processes use unless the user chose one.
PUBLICATION_MODE = "ASYNCHRONOUS"


def dds_defaults(env: MutableMapping[str, str] | None = None) -> MutableMapping[str, str]:
    """Put the package's DDS defaults into ``env`` (this process's environment when None,
    which must happen before ``rclpy.init``) where the user set nothing; returns ``env``."""
    target = os.environ if env is None else env
    target.setdefault(PUBLICATION_MODE_VAR, PUBLICATION_MODE)
    return target
