# hosid developer targets. `make demo` and `make test` are the quick start.
SHELL := /bin/bash
.DEFAULT_GOAL := test

VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: venv demo test lint test-slow bench analyses paper peers clean

venv: $(STAMP)

# Created once; re-installed whenever pyproject.toml changes.
$(STAMP): pyproject.toml
	@set -e; \
	if [ ! -x $(PY) ]; then \
		python=$$(tools/find-python.sh); \
		echo "creating $(VENV) with $$python"; \
		"$$python" -m venv $(VENV); \
	fi; \
	$(PY) -m pip install --upgrade --quiet pip; \
	$(PY) -m pip install --quiet -e '.[test,analyses]'; \
	touch $@

demo: $(STAMP)
	$(VENV)/bin/hosid demo --out demo-out

test: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks analyses
	$(PY) -m pytest -q

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks analyses
	$(VENV)/bin/ruff format --check src tests benchmarks analyses

test-slow: $(STAMP)
	$(PY) -m pytest -q -m slow

bench: $(STAMP)
	@if [ ! -d benchmarks ] || [ -z "$$(ls benchmarks/*.py 2>/dev/null)" ]; then \
		echo "make bench: no benchmarks/*.py yet" >&2; exit 1; fi
	$(PY) -m pytest -q --benchmark-only benchmarks

# The paper's Figures 1-8 by today's engine and its claims beside the measured numbers
# (analyses/out/paper/paper.md; about 2 minutes on 2 cores).
paper: $(STAMP)
	$(PY) analyses/paper_figures.py

# hosid beside the Kramers-Moyal and IV drift regressions, covariance-driven SSI and the
# paper's own estimators on the same 2 x 20 records (analyses/out/peers/peers.md; it
# resumes: delete records.csv to redo it).
peers: $(STAMP)
	$(PY) analyses/peers.py
	$(PY) analyses/monitor_study.py

# The statistical studies (hours on 2 cores; each resumes where it stopped): the
# information limit per regime, the efficiency and calibration of the default fit and of
# --cost J4A, the record checks' false alarms and detections, the diagnose confusion and
# power, the Silverbox (skipped, saying why, without its file).
analyses: $(STAMP)
	$(PY) analyses/crb.py
	$(PY) analyses/efficiency_study.py --cost default --records 20 --workers 2
	$(PY) analyses/efficiency_study.py --cost J4A --records 20 --workers 2
	$(PY) analyses/record_checks.py
	$(PY) analyses/diagnose_confusion.py
	$(PY) analyses/diagnose_power.py
	$(PY) analyses/silverbox.py
	$(PY) analyses/silverbox_coverage.py
	$(PY) analyses/paper_figures.py
	$(PY) analyses/peers.py
	$(PY) analyses/monitor_study.py

clean:
	rm -rf $(VENV) demo-out analyses/out .pytest_cache .benchmarks build src/*.egg-info
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
