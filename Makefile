# Two commands do everything on a fresh machine with Python 3.10+: `make demo` and `make test`.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo test test-all lint bench fuzz soak plots clean

$(STAMP): requirements.txt setup.py
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements.txt -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/crawler-motion demo

test: $(STAMP)
	$(PY) -m ruff check crawler_motion test scripts
	$(PY) -m pytest -q

lint: $(STAMP)
	$(PY) -m ruff check crawler_motion test scripts

bench: $(STAMP)
	$(PY) scripts/bench.py
	$(PY) scripts/smoothness_report.py --out plots

plots: $(STAMP)
	$(VENV)/bin/crawler-motion plot --out plots

clean:
	rm -rf $(VENV) build install log .pytest_cache .hypothesis
