# ccm — every target installs what it needs into .venv first (only Python 3.11 is assumed).
PY ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp
ARGS ?=
# the experiment `make run` runs: the headline one (seed A H4, Fig. 16); make run EXP=smoke is quicker
EXP ?= h4_collisions

.PHONY: setup run test test-slow lint format bench clean reproduce-paper reproduce-paper-quick

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

# every paper experiment (claims in experiments/claims.yaml); seeds come from each experiment
# config's hydra.sweeper.params; jobs run 2 at a time (hydra/launcher=local)
PAPER_EXPS := h1_forward_model h1_adaptive_control h2_changing_surface h3_long_horizon \
	h4_collisions h4_contact_learning h4_impactless mpc_convexity gp_contact_models \
	mpc_contact mpc_rail mpc_polishing mpc_goal_inference contact_head_to_head
PAPER_DIR ?= outputs/paper

reproduce-paper: setup  ## all paper experiments over their seeds, then ccm report (resumable)
	@status=0; for e in $(PAPER_EXPS); do \
	  $(BIN)/ccm run -m experiment=$$e hydra/launcher=local hydra.sweep.dir=$(PAPER_DIR)/$$e \
	    || status=1; \
	done; $(BIN)/ccm report $(PAPER_DIR) || status=1; exit $$status

reproduce-paper-quick: setup  ## the same pipeline with seed 0 and short trials (a smoke test)
	@status=0; for e in $(PAPER_EXPS); do \
	  $(BIN)/ccm run -m experiment=$$e seed=0 experiment.fast=true hydra/launcher=local \
	    hydra.sweep.dir=$(PAPER_DIR)-quick/$$e || status=1; \
	done; $(BIN)/ccm report $(PAPER_DIR)-quick || status=1; exit $$status

bench: setup  ## speed table; also writes bench.json
	$(BIN)/python -m ccm.bench --out bench.json

clean:
	rm -rf $(VENV) outputs multirun bench.json .pytest_cache .ruff_cache
