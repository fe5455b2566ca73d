"""ROS 2 message definitions (``ros2msg`` schema text) from the installed ``.msg`` files.

The text is what ``ros2 bag`` writes into an MCAP schema: the type's own ``.msg`` file, then
every type it uses, each under a line of 80 ``=`` and ``MSG: pkg/Type``. It is read from the
``share/<pkg>/msg/<Type>.msg`` files of the installed message packages, never written by hand.
"""

from __future__ import annotations

import os
import re
import sys
from functools import cache
from pathlib import Path

from crawler_motion.errors import CrawlerMotionError

#: Field types of the ROS 2 IDL that are not messages.
PRIMITIVES = frozenset({"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16",
                        "uint16", "int32", "uint32", "int64", "uint64", "string", "wstring"})
SEPARATOR = "=" * 80
_BOUNDS = re.compile(r"(<=\d+)?(\[[^\]]*\])?$")


def split_type(name: str) -> tuple[str, str]:
    """``pkg/msg/Type`` or ``pkg/Type`` -> (``pkg``, ``Type``); anything else is an error."""
    parts = name.split("/")
    if (len(parts) == 3 and parts[1] == "msg") or len(parts) == 2:
        if all(parts):
            return parts[0], parts[-1]
    raise CrawlerMotionError(f"message type {name!r}: expected 'pkg/msg/Type' or 'pkg/Type'")


def prefixes() -> list[Path]:
    """Install prefixes searched for message packages: ``AMENT_PREFIX_PATH`` (a ROS
    workspace), then this interpreter's prefix (a pip install puts ``share/`` there)."""
    paths = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    return [Path(p) for p in (*paths, sys.prefix)]


def msg_path(package: str, type_name: str) -> Path:
    """The installed ``.msg`` file of ``package/Type`` (`CrawlerMotionError` when missing)."""
    for prefix in prefixes():
        path = prefix / "share" / package / "msg" / f"{type_name}.msg"
        if path.is_file():
            return path
    raise CrawlerMotionError(f"no definition of {package}/msg/{type_name}: no "
                             f"share/{package}/msg/{type_name}.msg under "
                             f"{', '.join(str(p) for p in prefixes())}")


def field_types(text: str, package: str) -> list[tuple[str, str]]:
    """The message types (pkg, Type) the fields of the ``.msg`` ``text`` use, in order."""
    out: list[tuple[str, str]] = []
    for line in text.splitlines():
        words = line.split("#", 1)[0].split()
        if len(words) < 2 or "=" in words[1]:
            continue  # blank, comment or constant
        base = _BOUNDS.sub("", words[0])
        if base in PRIMITIVES:
            continue
        used = split_type(base) if "/" in base else (package, base)
        if used == ("std_msgs", "Header") or base == "Header":
            used = ("std_msgs", "Header")
        if used not in out:
            out.append(used)
    return out


@cache
def message_definition(name: str) -> str:
    """The ``ros2msg`` schema text of message type ``name`` (``pkg/msg/Type``)."""
    package, type_name = split_type(name)
    main = msg_path(package, type_name).read_text(encoding="utf-8")
    seen: list[tuple[str, str]] = []
    todo = field_types(main, package)
    while todo:
        dep = todo.pop(0)
        if dep in seen:
            continue
        seen.append(dep)
        todo += field_types(msg_path(*dep).read_text(encoding="utf-8"), dep[0])
    parts = [main.rstrip("\n")]
    for dep_package, dep_type in seen:
        text = msg_path(dep_package, dep_type).read_text(encoding="utf-8").rstrip("\n")
        parts.append(f"{SEPARATOR}\nMSG: {dep_package}/{dep_type}\n{text}")
    return "\n".join(parts) + "\n"
