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

# One BLAS/OpenMP thread per process: on 2 cores, oversubscribed threads are the usual
# slowdown (reproduce --quick: 102 s with one thread, 137 s without, measured back to back).
THREADS := OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1

# Main job: reproduce the paper (figures, tables, report in reports/; runs in mlruns/).
run: $(VENV)/.installed
	$(THREADS) $(VENV)/bin/workbench reproduce --out reports

# Default test suite (slow checks: `$(PY) -m pytest -m slow`). Two workers, one BLAS/OpenMP
# thread each.
test: $(VENV)/.installed-dev
	$(THREADS) $(PY) -m pytest -n 2

clean:
	rm -rf $(VENV) .cache
