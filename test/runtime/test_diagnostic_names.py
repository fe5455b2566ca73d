"""Tests of crawler_motion.runtime.diagnostic_names: a /diagnostics status's robot."""

from __future__ import annotations

import pytest

from crawler_motion.runtime.diagnostic_names import same_robot, status_namespace, status_prefix


@pytest.mark.parametrize(("namespace", "node", "prefix"), [
    ("/", "driver", "driver"), ("", "driver", "driver"),
    ("/crawler1", "driver", "crawler1/driver"), ("/team/crawler1/", "driver",
                                                  "team/crawler1/driver"),
])
def test_status_prefix(namespace: str, node: str, prefix: str) -> None:
    assert status_prefix(namespace, node) == prefix
    assert status_namespace(f"{prefix}: motor manager") == "/" + namespace.strip("/")


@pytest.mark.parametrize(("name", "namespace", "same"), [
    ("driver: motor manager", "/", True),
    ("driver: motor manager", "/crawler1", False),
    ("crawler1/driver: motor manager", "/crawler1", True),
    ("crawler1/driver: motor manager", "/crawler1/", True),
    ("crawler1/driver: motor manager", "/crawler2", False),
    ("crawler1/driver: motor manager", "/", False),
    ("team/crawler1/driver: x", "/team/crawler1", True),
    ("team/crawler1/driver: x", "/team", False),
    ("motor_manager/axes", "/crawler1", True),  # no "<node>: ": counts for every robot
    (": nothing before", "/crawler1", True),
    ("", "/", True),
])
def test_same_robot(name: str, namespace: str, same: bool) -> None:
    assert same_robot(name, namespace) is same
