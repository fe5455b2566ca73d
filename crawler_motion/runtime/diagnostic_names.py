"""Which robot a ``/diagnostics`` status belongs to, when several robots share one ROS graph.

Every node of the package works in a namespace (``--ros-args -r __ns:=/crawler1``) with
relative topic names, except ``/diagnostics``, which stays global as the ROS convention wants
(one aggregator sees every robot). A status is named ``<node>: <what>`` where ``<node>`` is the
publishing node's name, qualified by its namespace when it has one (`status_prefix`): e.g.
``driver: motor manager`` at the root, ``crawler1/driver: motor manager`` under ``/crawler1``.
A node reading ``/diagnostics`` keeps the statuses of its own namespace (`same_robot`). A name
without the ``<node>: `` form cannot be placed and counts for every robot (a fault of unknown
origin pauses rather than being ignored).

The keys that tools read from another node's status live here too (one spelling):
`BODY_CONTACTS_KEY`, `OBSTACLE_CONTACTS_KEY`, `FIRST_CONTACTS_KEY`.
"""

from __future__ import annotations

#: Separator between the node part and the rest of a status name.
SEPARATOR = ": "
#: Key of the simulator's count of manager ticks with the hull or a leg link in contact.
BODY_CONTACTS_KEY = "hull or leg contact ticks"
#: Key of the simulator's count of those ticks with anything but the seabed (an obstacle).
OBSTACLE_CONTACTS_KEY = "hull or leg obstacle contact ticks"
#: Key of the simulator's first hull or leg contacts: "seabed: <geom> on <geom> at <t> s; ...".
FIRST_CONTACTS_KEY = "first hull or leg contacts"


def status_prefix(namespace: str, node_name: str) -> str:
    """The node part of a status name: ``node_name``, or ``<namespace>/<node_name>`` (without
    the leading slash) under a namespace other than the root."""
    ns = namespace.strip("/")
    return f"{ns}/{node_name}" if ns else node_name


def status_namespace(status_name: str) -> str | None:
    """The namespace (``/`` or ``/crawler1``) of the node that named ``status_name``; None
    when the name has no ``<node>: `` part."""
    node, separator, _ = status_name.partition(SEPARATOR)
    if not separator or not node.strip():
        return None
    return "/" + node.rpartition("/")[0].strip("/")


def same_robot(status_name: str, namespace: str) -> bool:
    """True if the status belongs to the robot of ``namespace`` (or cannot be placed)."""
    owner = status_namespace(status_name)
    return owner is None or owner == "/" + namespace.strip("/")
