"""The file tree is the architecture: each subpackage imports only from the layers below it,
and the pure core never imports rclpy. Also: the size limits of the layout."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "crawler_motion"
#: Lowest layer first; a subpackage may import itself and any subpackage listed before it.
LAYERS: tuple[str, ...] = ("errors", "model", "motion", "calibration", "canbus", "runtime",
                           "planner", "driver", "controller", "mapping", "navigation", "sim",
                           "testing", "recording", "bringup", "tools")
#: Modules that may import rclpy / ROS message packages: the nodes, their ROS helpers, and
#: the tools and test stack on top; the pure core (everything else) never does.
ROS_MODULES = {"planner/node.py", "driver/node.py", "driver/rclpy_workarounds.py",
               "planner/contact_topics.py", "planner/measured_input.py", "planner/imu_input.py",
               "driver/messages.py", "driver/command_input.py", "controller/node.py",
               "runtime/ros_reader.py",
               "runtime/ros_parameters.py", "runtime/ros_main.py", "sim/seabed/node.py",
               "runtime/ros_diagnostics.py",
               "mapping/node.py", "navigation/node.py", "navigation/mission_topics.py",
               "navigation/body_inputs.py",
               "recording/recorder.py",
               "recording/view.py"}
ROS_LAYERS = {"testing", "tools"}
ROS_ROOTS = {"rclpy", "std_msgs", "sensor_msgs", "geometry_msgs", "nav_msgs",
             "diagnostic_msgs", "lifecycle_msgs", "rcl_interfaces", "std_srvs"}
MAX_MODULE_LINES = 400
MAX_CLASS_LINES = 250
MAX_FUNCTION_LINES = 60


def _modules() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def _imports(path: Path) -> set[str]:
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
        elif isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
    return names


def _layer(path: Path) -> str:
    rel = path.relative_to(PACKAGE)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_imports_go_down_the_layers_only(path: Path) -> None:
    layer = _layer(path)
    if layer not in LAYERS:  # the package's __init__
        return
    allowed = set(LAYERS[:LAYERS.index(layer) + 1])
    for name in _imports(path):
        parts = name.split(".")
        if parts[0] == "crawler_motion" and len(parts) > 1:
            assert parts[1] in allowed, f"{path.relative_to(PACKAGE)} imports {name}"


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_only_the_nodes_import_ros(path: Path) -> None:
    rel = path.relative_to(PACKAGE).as_posix()
    ros = {name for name in _imports(path) if name.split(".")[0] in ROS_ROOTS}
    assert not ros or rel in ROS_MODULES or _layer(path) in ROS_LAYERS, (
        f"{rel} imports {sorted(ros)}")


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_size_limits(path: Path) -> None:
    text = path.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= MAX_MODULE_LINES
    for node in ast.walk(ast.parse(text)):
        length = (node.end_lineno or node.lineno) - node.lineno + 1 if hasattr(
            node, "lineno") else 0
        if isinstance(node, ast.ClassDef):
            assert length <= MAX_CLASS_LINES, f"class {node.name}: {length} lines"
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            assert length <= MAX_FUNCTION_LINES, f"{node.name}: {length} lines"


def test_every_subpackage_says_what_it_is_in_one_line() -> None:
    for layer in LAYERS[1:]:
        init = PACKAGE / layer / "__init__.py"
        doc = ast.get_docstring(ast.parse(init.read_text(encoding="utf-8")))
        assert doc and "\n" not in doc.strip(), f"{layer}/__init__.py needs a one-line docstring"


def test_the_layer_rule_can_fail(tmp_path: Path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text("from crawler_motion.tools.cli import main\n")
    assert "crawler_motion.tools.cli" in _imports(bad)
