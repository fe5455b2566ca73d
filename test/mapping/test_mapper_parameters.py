"""The terrain_mapper's parameter sets: each value in its range and the whole within budget."""

from __future__ import annotations

import pytest

from crawler_motion.errors import ConfigError
from crawler_motion.mapping.parameters import (
    MAX_CELLS,
    budget_problems,
    mapper_parameters,
    mapper_settings,
)
from crawler_motion.model.config import load_config

SPECS = mapper_parameters(load_config())
DEFAULTS = {s.name: s.default for s in SPECS}


def test_the_defaults_fit_the_budget() -> None:
    assert mapper_settings(SPECS, DEFAULTS).cells == 80
    assert budget_problems(DEFAULTS["size"], DEFAULTS["resolution"], 10.0) == []


@pytest.mark.parametrize(("changes", "says"), [
    ({"size": 50.0, "resolution": 0.02}, "makes 6250000 cells, more than the budget"),
    ({"size": 20.0, "resolution": 0.04, "publish_rate": 10.0}, "cells/s, more than the budget"),
])
def test_a_set_of_values_each_in_range_that_cannot_run_is_refused(changes, says) -> None:
    with pytest.raises(ConfigError, match=says):
        mapper_settings(SPECS, {**DEFAULTS, **changes})


def test_the_largest_grid_runs_at_a_lower_rate() -> None:
    side = MAX_CELLS ** 0.5 * 0.02  # 500 x 500 cells of 2 cm
    assert budget_problems(side, 0.02, 2.0) == []
    assert budget_problems(side, 0.02, 10.0)


def test_the_mapper_process_refuses_a_grid_beyond_the_budget() -> None:
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-m", "crawler_motion.mapping.node", "--ros-args",
                           "-p", "size:=50.0", "-p", "resolution:=0.02"],
                          capture_output=True, text=True, timeout=30)
    assert proc.returncode == 1 and "more than the budget" in proc.stdout + proc.stderr
