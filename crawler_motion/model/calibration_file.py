"""Leg calibration files (YAML): the per-leg geometry, read with plausibility checks, written
merged with the legs already in the file.

Format (every key optional but ``legs``; a parameter left out keeps its nominal value, a leg
left out is nominal; lengths and displacements in m, angles in rad)::

    calibration:
      version: 2
      legs:
        lf: {l1: 0.0302, l2: 0.0597, root_offset: 0.0081, knee_twist: -0.0012, ...}
        rb: {...}

Parameter names and meaning: `crawler_motion.model.leg_geometry`. Version 2 (written since the
leg model is complete) adds ``knee_yaw``; a file without ``version`` is version 1 and loads
unchanged (its legs are the version-2 chain with ``knee_yaw`` = 0, the same feet), but it
was identified without the knee axis's yaw: `LegCalibration.note` says so and how to redo it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml

from crawler_motion.errors import CalibrationError
from crawler_motion.model.leg_geometry import INDEX, N_PARAMS, NAMES, implausible, nominal_params

#: Format version written; 1: the 16-parameter chain (no ``knee_yaw``).
VERSION = 2
#: Parameters a version-1 file cannot have.
NEW_IN_2 = ("knee_yaw",)

if TYPE_CHECKING:
    from crawler_motion.model.config import Config, RobotConfig


@dataclass(frozen=True)
class LegCalibration:
    """Geometry parameters ``(n_legs, N_PARAMS)`` of every leg (rows in ``legs`` order) and the
    nominal values they were checked against."""

    legs: tuple[str, ...]
    params: np.ndarray
    nominal: np.ndarray
    source: str = "<memory>"
    nominal_legs: tuple[bool, ...] = field(default=())
    version: int = VERSION

    def __post_init__(self) -> None:
        if not self.nominal_legs:
            flags = tuple(bool(np.array_equal(p, n)) for p, n in zip(self.params, self.nominal,
                                                                       strict=True))
            object.__setattr__(self, "nominal_legs", flags)

    @property
    def note(self) -> str:
        """Empty, or why the file should be identified again (a version-1 file)."""
        if self.version >= VERSION:
            return ""
        return (f"{self.source} is a version-{self.version} calibration, identified without the "
                f"knee axis's yaw (knee_yaw); it loads unchanged, but to absorb that error "
                f"identify the legs again (crawler-motion calibrate identify)")

    @property
    def is_nominal(self) -> bool:
        """True when every leg has exactly its nominal geometry."""
        return all(self.nominal_legs)

    def with_leg(self, leg: str, params: np.ndarray) -> LegCalibration:
        """A copy with ``leg``'s parameters replaced (checked for plausibility); it is written
        as the current version (the other legs' geometry is the same in it)."""
        i = self._index(leg)
        _check(params, self.nominal[i], f"leg {leg}")
        table = self.params.copy()
        table[i] = params
        return LegCalibration(self.legs, table, self.nominal, self.source)

    def _index(self, leg: str) -> int:
        if leg not in self.legs:
            raise CalibrationError(f"leg '{leg}' does not exist; the legs are {list(self.legs)}",
                                   key=leg)
        return self.legs.index(leg)


def nominal_calibration(legs: tuple[str, ...], links: tuple[float, float, float]
                        ) -> LegCalibration:
    """Every leg at the nominal geometry with links l1, l2, l3 [m]."""
    nominal = np.tile(nominal_params(*links), (len(legs), 1))
    return LegCalibration(tuple(legs), nominal.copy(), nominal)


def _check(params: np.ndarray, nominal: np.ndarray, where: str, path: Path | None = None) -> None:
    reasons = implausible(params, nominal)
    if reasons:
        raise CalibrationError(f"{where}: implausible calibration: {'; '.join(reasons)}",
                               path=path, key=where)


def _value(raw: Any, where: str, path: Path) -> float:
    if isinstance(raw, bool) or not isinstance(raw, (int, float)) or not math.isfinite(raw):
        raise CalibrationError(f"{where} must be a finite number, got {raw!r}", path=path,
                               key=where)
    return float(raw)


def parse_calibration(data: Any, legs: tuple[str, ...], links: tuple[float, float, float],
                      path: Path) -> LegCalibration:
    """Validate the YAML document ``data`` of a calibration file (see the module docstring)."""
    base = nominal_calibration(legs, links)
    section = data.get("calibration") if isinstance(data, Mapping) else None
    table = section.get("legs") if isinstance(section, Mapping) else None
    if not isinstance(table, Mapping):
        raise CalibrationError(f"{path}: needs a mapping 'calibration: legs: {{leg: {{param: "
                               f"value}}}}'", path=path)
    version = _version(section, path)
    params = base.params.copy()
    for leg, values in table.items():
        if leg not in legs:
            raise CalibrationError(f"{path}: leg '{leg}' does not exist; the legs are "
                                   f"{list(legs)}", path=path, key=str(leg))
        if not isinstance(values, Mapping):
            raise CalibrationError(f"{path}: calibration.legs.{leg} must map parameter names "
                                   f"to numbers", path=path, key=str(leg))
        i = legs.index(leg)
        for name, raw in values.items():
            if name not in INDEX:
                raise CalibrationError(f"{path}: calibration.legs.{leg}.{name} is not a "
                                       f"parameter; known: {', '.join(NAMES)}", path=path,
                                       key=f"{leg}.{name}")
            if version < 2 and name in NEW_IN_2:
                raise CalibrationError(f"{path}: calibration.legs.{leg}.{name} needs "
                                       f"'version: 2' under 'calibration:'", path=path,
                                       key=f"{leg}.{name}")
            params[i, INDEX[name]] = _value(raw, f"calibration.legs.{leg}.{name}", path)
        _check(params[i], base.nominal[i], f"{path}: leg {leg}", path)
    return LegCalibration(tuple(legs), params, base.nominal, str(path), version=version)


def _version(section: Mapping[str, Any], path: Path) -> int:
    raw = section.get("version", 1)
    if isinstance(raw, bool) or not isinstance(raw, int) or raw < 1:
        raise CalibrationError(f"{path}: calibration.version must be 1 or 2, got {raw!r}",
                               path=path, key="version")
    if raw > VERSION:
        raise CalibrationError(f"{path}: calibration version {raw} is newer than this "
                               f"crawler_motion reads (1 to {VERSION}): update crawler_motion, "
                               f"or identify the legs again with this one", path=path,
                               key="version")
    return raw


def _yaml_error(exc: yaml.YAMLError) -> str:
    """The YAML parser's complaint on one line (with its line and column when it has one)."""
    mark = getattr(exc, "problem_mark", None)
    problem = getattr(exc, "problem", None) or " ".join(str(exc).split())
    if mark is None:
        return problem
    return f"{problem} (line {mark.line + 1}, column {mark.column + 1})"


def load_calibration(path: str | Path, legs: tuple[str, ...],
                     links: tuple[float, float, float]) -> LegCalibration:
    """Read and check a calibration file for a robot with ``legs`` and nominal links [m].

    Raises `CalibrationError` for an unreadable file, unknown legs or parameters, non-numbers
    and implausible values (a link more than 10 % off, an angle beyond 10 deg).
    """
    file = Path(path)
    try:
        data = yaml.safe_load(file.read_text(encoding="utf-8"))
    except OSError as exc:
        raise CalibrationError(f"cannot read calibration file {file}: {exc.strerror}",
                               path=file) from exc
    except UnicodeDecodeError as exc:
        raise CalibrationError(f"calibration file {file} is not UTF-8 text ({exc})",
                               path=file) from exc
    except yaml.YAMLError as exc:
        raise CalibrationError(f"calibration file {file} is not valid YAML: {_yaml_error(exc)}",
                               path=file) from exc
    return parse_calibration(data, legs, links, file)


def with_calibration(robot: RobotConfig, path: str | Path | None) -> RobotConfig:
    """``robot`` with the per-leg geometry of the calibration file ``path`` (checked for
    plausibility against its nominal links); ``path`` None or empty: ``robot`` unchanged."""
    if path is None or str(path) == "":
        return robot
    geometry = load_calibration(path, robot.legs, (robot.l1, robot.l2, robot.l3))
    return replace(robot, geometry=geometry)


def config_with_calibration(cfg: Config, path: str | Path | None) -> Config:
    """``cfg`` whose robot has the calibration file ``path`` (`with_calibration`)."""
    return replace(cfg, robot=with_calibration(cfg.robot, path))


def calibration_yaml(calib: LegCalibration) -> str:
    """The YAML text of ``calib``: every parameter of every non-nominal leg."""
    table = {leg: {name: float(calib.params[i, k]) for k, name in enumerate(NAMES)}
             for i, leg in enumerate(calib.legs) if not calib.nominal_legs[i]}
    header = ("# Leg calibration of crawler_motion: per-leg geometry (lengths and displacements"
              " in m,\n# angles in rad; see crawler_motion/model/leg_geometry.py).\n")
    return header + yaml.safe_dump({"calibration": {"version": VERSION, "legs": table}},
                                   sort_keys=False)


def write_calibration(path: str | Path, calib: LegCalibration) -> None:
    """Write ``calib`` to ``path`` atomically (a temporary file renamed over it)."""
    file = Path(path)
    tmp = file.with_name(file.name + ".tmp")
    tmp.write_text(calibration_yaml(calib), encoding="utf-8")
    tmp.replace(file)


__all__ = ["N_PARAMS", "LegCalibration", "calibration_yaml", "config_with_calibration",
           "load_calibration",
           "nominal_calibration", "parse_calibration", "with_calibration", "write_calibration"]
