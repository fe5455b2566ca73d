"""World files: MJCF whose ``<worldbody>`` children and ``<asset>`` entries join the robot model.

A world file is an ordinary MJCF document (root ``<mujoco>``). Only two parts are used: the
children of ``<worldbody>`` (geoms, static bodies, lights) and the entries of ``<asset>``
(textures, materials, heightfields). Paths in ``file`` attributes are relative to the world
file. **The seabed** is recognised by name: the world must hold exactly one geom named
``seabed`` (a plane, heightfield or box); rocks, steps and walls are further geoms. World geoms
must not use the robot's geom group (see `SimSettings.robot_group`), which the range scanner
ignores.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from crawler_motion.errors import ConfigError
from crawler_motion.model.config import config_dir

#: Name of the geom that is the seabed.
SEABED = "seabed"
#: Geom types a seabed may have.
SEABED_TYPES = ("plane", "hfield", "box")
#: Default world: a flat seabed.
DEFAULT_WORLD = "flat.xml"


@dataclass(frozen=True)
class World:
    """The parts of a world file merged into the generated model."""

    source: str  # path of the file, for messages
    assets: tuple[ET.Element, ...]
    bodies: tuple[ET.Element, ...]  # children of <worldbody>


def worlds_dir() -> Path:
    """Directory of the shipped world files (``config/worlds``)."""
    return config_dir() / "worlds"


def world_path(name: str | Path | None) -> Path:
    """Path of a world: a shipped name (``"wall"``, ``"wall.xml"``) or a file path."""
    if name is None:
        return worlds_dir() / DEFAULT_WORLD
    path = Path(name)
    if path.is_file() or path.parent != Path("."):
        return path
    shipped = worlds_dir() / (path.name if path.suffix else f"{path.name}.xml")
    return shipped if shipped.is_file() else path


def load_world(name: str | Path | None = None) -> World:
    """Read and check a world file; raise `ConfigError` naming the file and the problem."""
    path = world_path(name)
    try:
        root = ET.parse(path).getroot()
    except OSError as exc:
        raise ConfigError(f"world file {path}: cannot read it ({exc.strerror})") from exc
    except ET.ParseError as exc:
        raise ConfigError(f"world file {path}: not valid XML ({exc})") from exc
    if root.tag != "mujoco":
        raise ConfigError(f"world file {path}: not MJCF (root element <{root.tag}>, "
                          f"expected <mujoco>)")
    worldbody = root.find("worldbody")
    if worldbody is None:
        raise ConfigError(f"world file {path}: no <worldbody>, so no seabed")
    assets = [entry for asset in root.findall("asset") for entry in asset]
    for entry in assets:
        _resolve_file(entry, path)
    for element in worldbody.iter():
        if "file" in element.attrib:
            _resolve_file(element, path)
    _check_seabed(worldbody, path)
    return World(source=str(path), assets=tuple(assets), bodies=tuple(worldbody))


def _resolve_file(element: ET.Element, path: Path) -> None:
    """Make a ``file`` attribute absolute; refuse a file that does not exist."""
    name = element.get("file")
    if name is None:
        return
    target = (path.parent / name).resolve()
    if not target.is_file():
        raise ConfigError(f"world file {path}: <{element.tag}> names the missing file '{name}'")
    element.set("file", str(target))


def _check_seabed(worldbody: ET.Element, path: Path) -> None:
    seabeds = [g for g in worldbody.iter("geom") if g.get("name") == SEABED]
    if len(seabeds) != 1:
        raise ConfigError(f"world file {path}: needs exactly one geom named '{SEABED}' "
                          f"(the seabed), found {len(seabeds)}")
    kind = seabeds[0].get("type", "sphere")
    if kind not in SEABED_TYPES:
        raise ConfigError(f"world file {path}: the '{SEABED}' geom is a {kind}; it must be "
                          f"one of {list(SEABED_TYPES)}")
