# ccm — every target installs what it needs into .venv first (only Python 3.11 is assumed).
PY ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp
ARGS ?=
# the experiment `make run` runs: the headline one (seed A H4, Fig. 16); make run EXP=smoke is quicker
EXP ?= h4_collisions

.PHONY: setup run test test-slow lint format bench clean

setup: $(STAMP)

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[dev]'
	touch $(STAMP)

run: setup  ## the default experiment, $(EXP) (extra Hydra overrides: make run ARGS="seed=3")
	$(BIN)/ccm run experiment=$(EXP) $(ARGS)

test: setup  ## the default test suite (slow-marked checks excluded)
	$(BIN)/python -m pytest -q

test-slow: setup  ## only the slow-marked checks (every experiment in fast mode, …)
	$(BIN)/python -m pytest -q -m slow

lint: setup
	$(BIN)/ruff check ccm tests
	$(BIN)/ruff format --check ccm tests

format: setup
	$(BIN)/ruff format ccm tests
	$(BIN)/ruff check --fix ccm tests

bench: setup  ## speed table; also writes bench.json
	$(BIN)/python -m ccm.bench --out bench.json

clean:
	rm -rf $(VENV) outputs multirun bench.json .pytest_cache .ruff_cache
