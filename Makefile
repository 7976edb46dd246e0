# hosid developer targets. `make demo` and `make test` are the quick start.
SHELL := /bin/bash
.DEFAULT_GOAL := test

VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
# The development environment's exact versions (every dependency of hosid and of its
# extras test, analyses and docs, for Python 3.12 on any platform); `make lock` writes it.
LOCK   := requirements/dev.lock
UV_VERSION := 0.13.9
UV     := $(VENV)/bin/uv
LOWEST := build/venv-lowest

.PHONY: venv lock demo test lint test-slow test-lowest bench analyses paper peers docs clean

venv: $(STAMP)

$(PY):
	@python=$$(tools/find-python.sh) && echo "creating $(VENV) with $$python" && \
		"$$python" -m venv $(VENV)

# The locked versions, then hosid itself (editable, no dependencies of its own: they are
# all in the lock); re-installed whenever the lock or pyproject.toml changes. pip check
# fails when the lock no longer satisfies pyproject.toml (then run make lock).
$(STAMP): pyproject.toml $(LOCK) | $(PY)
	@set -e; \
	$(PY) -m pip install --upgrade --quiet pip; \
	$(PY) -m pip install --quiet -r $(LOCK); \
	$(PY) -m pip install --quiet --no-deps -e .; \
	$(PY) -m pip check || { echo "$(LOCK) does not satisfy pyproject.toml: run make lock" >&2; exit 1; }; \
	touch $@

$(UV): | $(PY)
	$(PY) -m pip install --quiet uv==$(UV_VERSION)

# Regenerate the lock from pyproject.toml with uv. Pins that still satisfy pyproject.toml
# are kept; `make lock LOCKFLAGS=--upgrade` moves every pin to the newest allowed version
# (LOCKFLAGS='--upgrade-package numpy' just one).
lock: $(UV)
	$(UV) pip compile pyproject.toml --extra test --extra analyses --extra docs \
		--python-version 3.12 --universal --custom-compile-command 'make lock' \
		--quiet $(LOCKFLAGS) -o $(LOCK)

demo: $(STAMP)
	$(VENV)/bin/hosid demo --out demo-out

# The suite on every core (pytest-xdist), a test file to a worker so that a module's
# shared fixtures are built once; TEST_WORKERS=0 runs it in this process alone.
TEST_WORKERS ?= auto
test: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks analyses
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks analyses
	$(VENV)/bin/ruff format --check src tests benchmarks analyses

test-slow: $(STAMP)
	$(PY) -m pytest -q -m slow

# The lowest versions pyproject.toml allows (every direct dependency at its lower bound,
# the rest resolved to today's) in a throwaway venv, and a few quick tests on them (about
# 4 minutes). Deprecation warnings are not errors here: old releases emit them under
# today's transitive dependencies (matplotlib 3.9.0 under pyparsing 3.3).
test-lowest: $(UV)
	@set -e; \
	rm -rf $(LOWEST); \
	"$$(tools/find-python.sh)" -m venv $(LOWEST); \
	$(UV) pip compile pyproject.toml --extra test --python-version 3.12 \
		--resolution lowest-direct --quiet -o $(LOWEST)/requirements.txt; \
	$(LOWEST)/bin/python -m pip install --quiet -r $(LOWEST)/requirements.txt; \
	$(LOWEST)/bin/python -m pip install --quiet --no-deps -e .; \
	$(LOWEST)/bin/python -m pytest -q -p no:cacheprovider -W ignore::DeprecationWarning \
		tests/test_record.py tests/test_output.py tests/test_packaging.py \
		tests/test_batch.py::test_one_and_two_workers_give_identical_tables

# The documentation site, docs/_build/html/index.html: the pages, the API reference from
# the docstrings, the examples gallery executed, the measured numbers read from
# analyses/results. Every warning is an error; -E rereads every page so that a rerun
# reports them again. An example reruns when it changes (rm -rf docs/auto_examples to
# rerun them all). From a clean clone about 5 minutes on 2 cores.
docs: $(STAMP)
	OPENBLAS_NUM_THREADS=1 $(VENV)/bin/sphinx-build -W --keep-going -E -b html docs docs/_build/html

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
	rm -rf $(VENV) demo-out analyses/out .pytest_cache .benchmarks build dist src/*.egg-info \
		docs/_build docs/auto_examples docs/gen_modules docs/measured/_generated \
		docs/guide/_generated docs/sg_execution_times.rst
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
