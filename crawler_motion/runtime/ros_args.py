"""``--ros-args`` for a program that is not an rclpy node (no ROS needed), as rcl reads them.

Understood: ``-p`` / ``--param name:=value`` (also ``node:name:=value`` for one node), the value
read as YAML like rcl does; ``--params-file FILE`` (ROS parameter YAML: sections keyed by node,
``/**`` and ``*`` wildcards and nested namespaces allowed, ``ros__parameters`` below, nested
groups joined with dots); ``-r`` / ``--remap`` ``__node:=`` and ``__ns:=`` (they decide which
sections and node-specific parameters apply; other remaps have no topic to act on here and are
accepted); and the logging and enclave options (accepted, ignored). Later settings win. Anything
else is a `ConfigError` naming it.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from crawler_motion.errors import ConfigError

#: Options that take one value and do not concern a program without ROS.
IGNORED_WITH_VALUE = frozenset({"--log-level", "--log-config-file", "-e", "--enclave",
                                "--log-file-name"})
#: Options without a value that do not concern a program without ROS.
IGNORED_FLAGS = frozenset({"--enable-rosout-logs", "--disable-rosout-logs",
                           "--enable-stdout-logs", "--disable-stdout-logs",
                           "--enable-external-lib-logs", "--disable-external-lib-logs"})


@dataclass
class RosArgs:
    """What ``--ros-args`` said to one node: its name, namespace and parameters."""

    node_name: str
    namespace: str = "/"
    parameters: dict[str, Any] = field(default_factory=dict)
    explicit: set[str] = field(default_factory=set)  # names set by -p (not by a file)

    @property
    def fully_qualified_name(self) -> str:
        """``/namespace/node_name``."""
        return f"{self.namespace.rstrip('/')}/{self.node_name}"


def _split(text: str, option: str) -> tuple[str, str]:
    name, sep, value = text.partition(":=")
    if not sep or not name:
        raise ConfigError(f"{option} {text!r}: expected name:=value")
    return name, value


def _node_matches(pattern: str, fqn: str) -> bool:
    """rcl's section match: ``/**`` any namespaces, ``*`` one token; no leading slash means
    relative to the root."""
    pattern = "/" + pattern.lstrip("/")
    regex = "".join("(/[^/]+)*" if part == "**" else "/[^/]+" if part == "*"
                    else "/" + re.escape(part) for part in pattern.strip("/").split("/"))
    return re.fullmatch(regex, fqn) is not None


def _flatten(values: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in values.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            out.update(_flatten(value, f"{name}."))
        else:
            out[name] = value
    return out


def _sections(tree: Mapping[str, Any], prefix: str = "") -> list[tuple[str, dict[str, Any]]]:
    """(node key, parameters) of a parameter file, nested namespaces joined with '/'."""
    out = []
    for key, value in tree.items():
        if not isinstance(value, Mapping):
            raise ConfigError(f"parameter file: {prefix}{key} must hold a mapping")
        if "ros__parameters" in value:
            params = value["ros__parameters"]
            if not isinstance(params, Mapping):
                raise ConfigError(f"parameter file: {prefix}{key}.ros__parameters must be a "
                                  f"mapping")
            out.append((f"{prefix}{key}", _flatten(params)))
        else:
            out.extend(_sections(value, f"{prefix}{key}/"))
    return out


def read_params_file(path: str, fqn: str) -> dict[str, Any]:
    """The parameters ``path`` gives the node ``fqn`` (sections in file order)."""
    try:
        tree = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError) as exc:
        raise ConfigError(f"--params-file {path}: {exc}") from exc
    if not isinstance(tree, Mapping):
        raise ConfigError(f"--params-file {path}: not a mapping of node sections")
    out: dict[str, Any] = {}
    for key, params in _sections(tree):
        if _node_matches(key, fqn):
            out.update(params)
    return out


def parse_ros_args(argv: Sequence[str], node_name: str) -> RosArgs:
    """Read the ``--ros-args`` sections of ``argv`` for the node ``node_name``."""
    result = RosArgs(node_name)
    settings: list[tuple[str, str]] = []  # ("param" | "file", text), in order
    items = list(argv)
    i = 0
    while i < len(items):
        arg = items[i]
        takes = arg in ("-p", "--param", "--params-file", "-r", "--remap", *IGNORED_WITH_VALUE)
        if takes and i + 1 >= len(items):
            raise ConfigError(f"--ros-args: {arg} needs a value")
        value = items[i + 1] if takes else ""
        if arg in ("-p", "--param"):
            settings.append(("param", value))
        elif arg == "--params-file":
            settings.append(("file", value))
        elif arg in ("-r", "--remap"):
            _remap(result, value)
        elif arg not in (*IGNORED_WITH_VALUE, *IGNORED_FLAGS, "--ros-args", "--"):
            raise ConfigError(f"--ros-args: {arg!r} is not understood here")
        i += 2 if takes else 1
    fqn = result.fully_qualified_name
    for kind, text in settings:
        if kind == "file":
            result.parameters.update(read_params_file(text, fqn))
            continue
        name, raw = _split(text, "-p")
        node, _, name = name.rpartition(":")
        if not node or node == result.node_name:
            result.parameters[name] = yaml.safe_load(raw) if raw.strip() else ""
            result.explicit.add(name)
    return result


def _remap(result: RosArgs, text: str) -> None:
    rule, value = _split(text, "-r")
    node, _, rule = rule.rpartition(":")
    if node and node != result.node_name:
        return
    if rule == "__node":
        result.node_name = value
    elif rule == "__ns":
        result.namespace = "/" + value.strip("/")
