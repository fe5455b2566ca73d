"""The console's wait for the planner: the planner's own gait_command subscription must be on
the graph before a command is sent (a new console may know only the recorder's and the
driver's yet, and the command would never reach the planner)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from crawler_motion.tools.console import planner_listens


def infos(*names: str, namespace: str = "/") -> list[SimpleNamespace]:
    return [SimpleNamespace(node_name=n, node_namespace=namespace) for n in names]


@pytest.mark.parametrize("publishers, subscribers, listens", [
    (infos("planner"), infos("recorder", "driver", "planner"), True),
    (infos("controller"), infos("controller"), True),  # composed: one node
    (infos("planner"), infos("recorder", "driver"), False),  # the planner's not known yet
    ([], infos("recorder", "driver", "planner"), False),  # no status publisher known
    (infos("planner"), infos("planner", namespace="/robot2"), False),  # another robot's
])
def test_the_planner_must_listen_to_gait_command(publishers, subscribers, listens) -> None:
    assert planner_listens(publishers, subscribers) is listens
