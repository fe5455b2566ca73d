"""Tests of crawler_motion.tools.param_docs: the committed parameter page matches the code."""

from __future__ import annotations

from pathlib import Path

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


def test_check_mode_reports_drift(tmp_path: Path, capsys) -> None:
    page = tmp_path / "parameters.md"
    assert param_docs.main(["--out", str(page)]) == 0
    assert param_docs.main(["--out", str(page), "--check"]) == 0
    page.write_text(page.read_text().replace("`rate`", "`rates`"))
    assert param_docs.main(["--out", str(page), "--check"]) == 1
    assert "out of date" in capsys.readouterr().err
