# The README's two commands. Both create .venv if it is missing and install the project.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
export MLFLOW_DISABLE_TELEMETRY := true
export MPLCONFIGDIR := $(CURDIR)/.cache/matplotlib

.PHONY: run test clean

$(PY):
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --upgrade pip

$(VENV)/.installed: pyproject.toml | $(PY)
	$(PY) -m pip install -e .
	touch $@

$(VENV)/.installed-dev: pyproject.toml | $(PY)
	$(PY) -m pip install -e ".[dev]"
	touch $@ $(VENV)/.installed

# One BLAS/OpenMP thread per test worker: two workers on 2 cores would oversubscribe.
# (For the single-process main job it made no clear difference: reproduce --quick took
# 113 and 120 s with one thread, 103 and 117 s without, alternating runs on an idle machine.)
THREADS := OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1

# Main job: reproduce the paper (figures, tables, report in reports/; runs in mlruns/).
run: $(VENV)/.installed
	$(VENV)/bin/workbench reproduce --out reports

# Default test suite (slow checks: `$(PY) -m pytest -m slow`). Two workers; a file's tests
# stay on one worker, so module-scoped fixtures (a reproduce run, a sweep) run once.
test: $(VENV)/.installed-dev
	$(THREADS) $(PY) -m pytest -n 2 --dist loadfile

clean:
	rm -rf $(VENV) .cache
