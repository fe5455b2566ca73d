"""rcl_interfaces parameter descriptors built from `ParamSpec` declarations, and the values
read back.

A choice parameter is declared with dynamic typing: YAML reads some choices as booleans
(``-p attitude_mode:=off`` is False), which a string parameter would refuse at declaration;
`parameter_values` gives them back as written (`parameters.choice_from_yaml`).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter

from crawler_motion.runtime.parameters import ParamSpec, choice_from_yaml


def descriptor(spec: ParamSpec) -> ParameterDescriptor:
    """The ROS descriptor of one parameter: description, read-only flag, range, choices."""
    result = ParameterDescriptor(name=spec.name, description=spec.description,
                                 read_only=spec.read_only)
    if spec.choices:
        result.additional_constraints = f"one of {list(spec.choices)}"
        result.dynamic_typing = True  # a choice YAML reads as a bool is given back as text
    if spec.minimum is not None and spec.maximum is not None:
        if isinstance(spec.default, float):
            result.floating_point_range = [FloatingPointRange(
                from_value=float(spec.minimum), to_value=float(spec.maximum), step=0.0)]
        else:
            result.integer_range = [IntegerRange(
                from_value=int(spec.minimum), to_value=int(spec.maximum), step=1)]
    return result


def parameter_values(node: Node, specs: Sequence[ParamSpec],
                     changes: Iterable[Parameter] = ()) -> dict[str, Any]:
    """The values of ``specs`` declared on ``node``, with ``changes`` (a set in progress)
    applied; choices as written (`parameters.choice_from_yaml`)."""
    values = {spec.name: node.get_parameter(spec.name).value for spec in specs}
    for param in changes:
        values[param.name] = param.value
    return {spec.name: choice_from_yaml(spec, values[spec.name]) for spec in specs}
