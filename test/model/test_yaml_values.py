"""The checked YAML values: one rule for a number in a range, its boundaries and its message."""

from __future__ import annotations

import math

import pytest

from crawler_motion.errors import ConfigError
from crawler_motion.model.yaml_values import number_in, positive


@pytest.mark.parametrize("value, above, ok", [
    (0.0, False, True), (1.0, False, True), (0.5, False, True), (1, False, True),
    (-1e-12, False, False), (1.0 + 1e-12, False, False),
    (0.0, True, False), (1e-12, True, True),  # an open lower end
    (math.nan, False, False), (math.inf, False, False), (True, False, False),
    ("0.5", False, False), (None, False, False),
])
def test_a_number_in_a_range(value, above, ok):
    if ok:
        assert number_in(value, "x", 0.0, 1.0, "m", above=above) == float(value)
        return
    with pytest.raises(ConfigError) as exc:
        number_in(value, "foothold x", 0.0, 1.0, "m", above=above)
    assert str(exc.value) == (f"foothold x must be a number in {'(' if above else '['}0, 1] m, "
                              f"got {value!r}")


@pytest.mark.parametrize("value", [0.0, -1.0, math.nan, False])
def test_positive_refuses(value):
    with pytest.raises(ConfigError, match="x must be"):
        positive(value, "x")
