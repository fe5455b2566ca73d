"""rcl_interfaces parameter descriptors built from `ParamSpec` declarations."""

from __future__ import annotations

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

from crawler_motion.runtime.parameters import ParamSpec


def descriptor(spec: ParamSpec) -> ParameterDescriptor:
    """The ROS descriptor of one parameter: description, read-only flag, range, choices."""
    result = ParameterDescriptor(name=spec.name, description=spec.description,
                                 read_only=spec.read_only)
    if spec.choices:
        result.additional_constraints = f"one of {list(spec.choices)}"
    if spec.minimum is not None and spec.maximum is not None:
        if isinstance(spec.default, float):
            result.floating_point_range = [FloatingPointRange(
                from_value=float(spec.minimum), to_value=float(spec.maximum), step=0.0)]
        else:
            result.integer_range = [IntegerRange(
                from_value=int(spec.minimum), to_value=int(spec.maximum), step=1)]
    return result
