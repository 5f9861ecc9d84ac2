# The two commands of README.md. Both create .venv if it is missing and install the project with
# its dev extra (tests, lint, docs) and the exact versions of requirements.lock (constraints:
# every package pinned): one install that `make run`, `make test` and `make docs` share.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
export MLFLOW_DISABLE_TELEMETRY := true
export MPLCONFIGDIR := $(CURDIR)/.cache/matplotlib

.PHONY: install run test lint lock clean browser bench bench-peers bench-outside docs house layout

# The installer: uv (PyPI's `uv`; a system one on PATH, else bootstrapped into the venv by pip),
# which resolves and downloads in parallel; pip where uv cannot be had. uv reads no pip.conf:
# an index pip is configured with (global.index-url or PIP_INDEX_URL) is handed to it, else
# both use PyPI.
UV_VERSION ?= 0.13.9
UV ?= $(shell command -v uv 2>/dev/null)
PIP_INDEX = $(or $(PIP_INDEX_URL),$(shell $(PYTHON) -m pip config get global.index-url 2>/dev/null))
INSTALLED := $(VENV)/.installed-dev

$(PY):
	$(PYTHON) -m venv $(VENV)

$(INSTALLED): pyproject.toml requirements.lock | $(PY)
	@uv="$(UV)"; \
	if [ -z "$$uv" ] && $(PY) -m pip install -q "uv==$(UV_VERSION)"; then uv=$(VENV)/bin/uv; fi; \
	if [ -n "$$uv" ]; then \
	  echo "$$uv pip install -c requirements.lock -e .[dev]"; \
	  $(if $(PIP_INDEX),UV_INDEX_URL="$${UV_INDEX_URL:-$(PIP_INDEX)}") \
	    $$uv pip install --python $(PY) -c requirements.lock -e ".[dev]"; \
	else \
	  echo "uv unavailable: installing with pip"; \
	  $(PY) -m pip install --upgrade pip && \
	  $(PY) -m pip install -c requirements.lock -e ".[dev]"; \
	fi
	touch $@

install: $(INSTALLED)

# One BLAS/OpenMP thread per test worker: two workers on 2 cores would oversubscribe.
# (For the single-process main job it made no clear difference: reproduce --quick took
# 113 and 120 s with one thread, 103 and 117 s without, alternating runs on an idle machine.)
THREADS := OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1

# Main job: reproduce the paper (figures, tables, report in reports/; runs in mlruns/), then
# README.md's results remade from reports/results.json (benchmarks/tables.py --readme).
run: $(INSTALLED)
	$(VENV)/bin/workbench reproduce --out reports
	$(PY) benchmarks/tables.py --readme reports/results.json

# Benchmarks (about 25 minutes; run alone on a quiet machine): the scaling, bootstrap and
# reference figures, and a newcomer's first two commands (a fresh install, make run's
# reproduction, make test's suite with each file's CPU seconds) beside the reference script's
# time, as JSON under benchmarks/results/, then docs/benchmarks.md's tables remade
# from them (benchmarks/tables.py; a test checks the page against the JSON). The reference side runs
# where its virtualenv exists (bash ../shared/bench/reference/setup.sh /tmp/reference-venv).
bench: $(INSTALLED)
	$(PY) benchmarks/scaling.py --max-rows 30000 --json benchmarks/results/scaling.json
	$(PY) benchmarks/bootstrap.py --json benchmarks/results/bootstrap.json
	$(PY) benchmarks/vs_reference.py --json benchmarks/results/reference.json
	$(PY) benchmarks/first_run.py --fresh --json benchmarks/results/first_run.json \
	  --suite-json benchmarks/results/suite_cost.json
	$(PY) benchmarks/tables.py

# The recommended config against the peer on every benchmark split (about 25 minutes):
# benchmarks/results/peers.json and docs/benchmarks.md's table made from it.
bench-peers: $(INSTALLED)
	$(PY) benchmarks/peers.py --datasets ibm ibm_devices google chain \
	  --seeds 0 1 2 3 4 5 --json benchmarks/results/peers.json
	$(PY) benchmarks/tables.py

# The recommended config against the prior and the peer on ten outside sets (real data with a
# physics prior, honest splits; benchmarks/outside_data.py fetches them from pinned wheels):
# benchmarks/results/outside.json and docs/benchmarks.md's win/loss table made from it. Long
# (the peer's 50 trials and the config's 50 candidates per set); run it alone. A reduced run
# for a quick look: benchmarks/outside.py --trials 10 --set model.draws=6 (marked reduced).
bench-outside: $(INSTALLED)
	$(THREADS) $(PY) benchmarks/outside.py --json benchmarks/results/outside.json
	$(PY) benchmarks/tables.py

# The documentation site (docs/, Sphinx) into docs/_build/html: offline, warnings as errors,
# the gallery's examples run. The config and CLI references are generated from the code.
# Open docs/_build/html/index.html.
docs: $(INSTALLED)
	$(THREADS) MPLBACKEND=Agg $(PY) -m sphinx -b html -W --keep-going docs docs/_build/html

# Lint (ruff) and type check (mypy), on the paths pyproject.toml's [tool.ruff] and
# [tool.mypy] cover.
lint: $(INSTALLED)
	$(VENV)/bin/ruff check
	$(VENV)/bin/mypy

# Sizes as a review signal, not a test: the modules over 400 lines and the functions over 80
# (benchmarks/house.py; it never fails: a long module with one concern is left whole).
house:
	$(PYTHON) benchmarks/house.py

# docs/user_guide/layout.md, generated from the packages' docstrings and imports
# (tools/layout.py; tests/test_layering.py checks it is up to date).
layout:
	$(PYTHON) tools/layout.py

# The browser test (tests/test_ui_browser.py) renders MLflow's UI in headless Chromium:
# Debian's package, installed once if missing (as root, or through sudo).
browser:
	@command -v chromium >/dev/null || command -v chromium-browser >/dev/null || { \
	  echo "installing Debian's chromium (for tests/test_ui_browser.py)"; \
	  SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	  $$SUDO env DEBIAN_FRONTEND=noninteractive apt-get update -qq && \
	  $$SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; }

# Default test suite after the lint and type checks (slow checks: `$(PY) -m pytest -m slow`).
# Two workers; a file's tests stay on one worker, so module-scoped fixtures (a reproduce run,
# a sweep) run once. Files go to the workers in the order tests/conftest.py collects them
# (the longest first), not xdist's default (the files with the most tests first).
test: lint browser
	$(THREADS) $(PY) -m pytest -n 2 --dist loadfile --no-loadscope-reorder

# Regenerate requirements.lock: the newest versions pyproject.toml allows (with the dev
# extra), resolved in a throwaway venv by $(PYTHON) (3.11, the oldest Python the project
# supports). Then run `make test` and commit the lock.
LOCKVENV := .cache/lockvenv
lock:
	rm -rf $(LOCKVENV)
	$(PYTHON) -m venv $(LOCKVENV)
	$(LOCKVENV)/bin/python -m pip install --upgrade pip
	$(LOCKVENV)/bin/python -m pip install -e ".[dev]"
	( echo "# The exact versions \`make run\`, \`make test\` and \`make docs\` install (one install of .[dev]):"; \
	  echo "# constraints, uv pip install -c requirements.lock -e \".[dev]\". Resolved for $$($(LOCKVENV)/bin/python -V)"; \
	  echo "# by \`make lock\` (pip freeze --exclude-editable of a fresh venv after"; \
	  echo "# pip install -e \".[dev]\"); regenerate with it, do not edit by hand."; \
	  $(LOCKVENV)/bin/python -m pip freeze --exclude-editable ) > requirements.lock.tmp
	mv requirements.lock.tmp requirements.lock
	rm -rf $(LOCKVENV)

clean:
	rm -rf $(VENV) .cache
