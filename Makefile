# Two commands do everything on a fresh machine with Python 3.10+: `make demo` and `make test`.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo test test-live test-all lint bench fuzz soak soak-mission plots mission clean calibration-figures

$(STAMP): requirements.txt setup.py
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements.txt -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/crawler-motion demo

test: $(STAMP)
	$(PY) -m ruff check crawler_motion test
	$(PY) -m pytest -q

# The real-time navigation tests alone (part of `make test`, about 6 minutes): the wall both
# ways, the U trap, the three follow stand-offs and the short harbour mission.
test-live: $(STAMP)
	$(PY) -m pytest -q test/navigation/test_live_navigation.py test/navigation/test_live_mission.py

fuzz: $(STAMP)
	FUZZ_EXAMPLES=10000 $(PY) -m pytest -q -s test/system/test_fuzz_chain.py test/planner/test_commands.py -k fuzz

calibration-figures: $(STAMP)
	RIGID_DRAWS=50 $(PY) -m pytest -q -s test/calibration/test_session.py

lint: $(STAMP)
	$(PY) -m ruff check crawler_motion test

bench: $(STAMP)
	$(VENV)/bin/crawler-motion bench $(if $(PEER),--peer $(PEER))
	$(VENV)/bin/crawler-motion smoothness --out plots
	$(VENV)/bin/crawler-motion bench --e2e
	$(VENV)/bin/crawler-motion bench-mission

# The whole stack walking for 10 minutes on the cross-process bus; exit 1 if anything was lost.
soak: $(STAMP)
	$(VENV)/bin/crawler-motion soak --rate 200 --duration 600

# Missions for 30 minutes on the simulated stack with faults injected (kills, stops, CAN
# garbage, e-stop, future odometry, goal floods), each checked; the report on stdout.
soak-mission: $(STAMP)
	$(VENV)/bin/crawler-motion soak --mission config/missions/soak.yaml --duration 1800

# The shipped harbour mission on the real-time stack (about 17 minutes): figures printed,
# recorded to mission.mcap and drawn in mission-report/.
mission: $(STAMP)
	$(VENV)/bin/crawler-motion mission config/missions/harbour.yaml --sim harbour \
		--record mission.mcap; s=$$?; \
		$(VENV)/bin/crawler-motion report mission.mcap -o mission-report; exit $$s

plots: $(STAMP)
	$(VENV)/bin/crawler-motion plot --out plots

clean:
	rm -rf $(VENV) build install log .pytest_cache .hypothesis
