# ccm — every target installs what it needs into .venv first (only Python 3.11 is assumed).
PY ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp
ARGS ?=
# the experiment `make run` runs: the headline one (seed A H4, Fig. 16); make run EXP=smoke is quicker
EXP ?= h4_collisions

.PHONY: setup run test test-slow lint format bench clean reproduce-paper reproduce-paper-quick browser mutation suite-results docs

setup: $(STAMP)

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[dev]'
	touch $(STAMP)

run: setup  ## the default experiment, $(EXP) (extra Hydra overrides: make run ARGS="seed=3")
	$(BIN)/ccm run experiment=$(EXP) $(ARGS)

# pytest workers (pytest-xdist): the suite takes ~8 min on two cores (7 min 32 s, 2026-12-07)
TEST_WORKERS ?= 2

test: setup browser  ## the default test suite (slow-marked checks excluded), on TEST_WORKERS cores
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS)

# headless Chromium for the report render test (tests/test_report_render.py): Debian's
# chromium package, installed when missing and apt-get runs as root; otherwise that test skips
browser:
	@command -v chromium >/dev/null 2>&1 || { \
	  if command -v apt-get >/dev/null 2>&1 && [ "$$(id -u)" = 0 ]; then \
	    echo "installing Debian's chromium (for the report render test)"; \
	    DEBIAN_FRONTEND=noninteractive apt-get install -y -q chromium >/dev/null 2>&1 || \
	    { apt-get update -q >/dev/null 2>&1 && \
	      DEBIAN_FRONTEND=noninteractive apt-get install -y -q chromium >/dev/null 2>&1; } || \
	    echo "note: could not install chromium; the report render test will be skipped"; \
	  else echo "note: chromium missing (needs apt-get as root); the report render test will be skipped"; fi; }

test-slow: setup  ## only the slow-marked checks (every experiment in fast mode, …)
	$(BIN)/python -m pytest -q -m slow

lint: setup
	$(BIN)/ruff check ccm tests tools
	$(BIN)/ruff format --check ccm tests tools

format: setup
	$(BIN)/ruff format ccm tests tools
	$(BIN)/ruff check --fix ccm tests tools

# every paper experiment (claims in experiments/claims.yaml; the list is ccm.reporting.paper's) over the
# seeds in its config's hydra.sweeper.params, two sweeps at a time, then ccm report
PAPER_DIR ?= outputs/paper

reproduce-paper: setup  ## all paper experiments over their seeds, then ccm report (resumable)
	$(BIN)/ccm paper --out $(PAPER_DIR)

reproduce-paper-quick: setup  ## the same pipeline with seed 0 and short trials (a smoke test)
	$(BIN)/ccm paper --quick --out $(PAPER_DIR)-quick

# the stored results `ccm suite` ranks a controller against (ccm/suite/results/<suite>/): every
# built-in entry of configs/suite/changing_contact_v1.yaml over the whole suite, two jobs at a time
suite-results: setup  ## regenerate the built-in controllers' stored suite results
	$(BIN)/ccm suite --regenerate

bench: setup  ## speed table; also writes bench.json
	$(BIN)/python -m ccm.bench --out bench.json --paper-dir $(PAPER_DIR)

# the documentation site (issue #43; mkdocs.yml): the docs extra (also in dev), then a strict
# build, so a broken link or a docstring mkdocstrings cannot read fails it
DOCS_STAMP := $(VENV)/.docs-stamp

$(DOCS_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[docs]'
	touch $(DOCS_STAMP)

docs: setup $(DOCS_STAMP)  ## the documentation site into site/ (open site/index.html)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict -d site  # the theme's end-of-life banner off (docs/index.md)

mutation: setup  ## mutation testing of the equations' packages (issue #39; not in CI; ARGS=target ...)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check 'mutmut==3.8.1'
	$(BIN)/python tools/mutation.py $(ARGS)

clean:
	rm -rf $(VENV) outputs multirun bench.json .pytest_cache .ruff_cache site
