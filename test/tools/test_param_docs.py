"""Tests of crawler_motion.tools.param_docs: the committed parameter page matches the code."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from crawler_motion.model.config import load_config
from crawler_motion.tools import param_docs

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / param_docs.DEFAULT_OUT


def test_committed_page_matches_the_declarations() -> None:
    assert PAGE.read_text(encoding="utf-8") == param_docs.render(load_config()), (
        "docs/parameters.md is out of date: run `crawler-motion param-docs`")


def test_every_declared_parameter_has_a_row() -> None:
    from crawler_motion.driver.settings import PARAMETERS
    from crawler_motion.planner.parameters import planner_parameters
    from crawler_motion.sim.seabed.parameters import SEABED_PARAMETERS

    text = param_docs.render(load_config())
    for spec in (*PARAMETERS, *planner_parameters(load_config(), ""), *SEABED_PARAMETERS):
        assert f"| `{spec.name}` |" in text


def test_committed_params_file_matches_the_declarations() -> None:
    assert (ROOT / param_docs.PARAMS_OUT).read_text(encoding="utf-8") == (
        param_docs.render_params(load_config())), (
        "config/params.yaml is out of date: run `crawler-motion param-docs`")


def test_check_mode_reports_drift(tmp_path: Path, capsys) -> None:
    page, params = tmp_path / "parameters.md", tmp_path / "params.yaml"
    files = ["--out", str(page), "--params-out", str(params)]
    assert param_docs.main(files) == 0
    assert param_docs.main([*files, "--check"]) == 0
    page.write_text(page.read_text().replace("`rate`", "`rates`"))
    assert param_docs.main([*files, "--check"]) == 1
    assert "parameters.md is out of date" in capsys.readouterr().err
    assert param_docs.main(files) == 0
    params.write_text(params.read_text().replace("rate: 100.0", "rate: 100"))
    assert param_docs.main([*files, "--check"]) == 1
    assert "params.yaml is out of date" in capsys.readouterr().err


@pytest.mark.parametrize(("value", "text"), [
    (True, "true"), (False, "false"), (3, "3"), (0.5, "0.5"), (100.0, "100.0"),
    (1e-05, "1.0e-05"), (2.5e-07, "2.5e-07"), ("wave", '"wave"'), ("", '""'),
    ((0.0, 1.5), "[0.0, 1.5]")])
def test_params_file_values_read_back_with_their_type(value, text) -> None:
    assert param_docs._yaml_value(value) == text
    back = yaml.safe_load(text)
    assert back == (list(value) if isinstance(value, tuple) else value)
    assert type(back) is (list if isinstance(value, tuple) else type(value))
