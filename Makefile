# feeler — the two commands a newcomer needs: `make demo` and `make test`.
# Both create the environment (uv, exact versions from uv.lock) when it is missing or stale.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
UV := $(PYTHON) -m uv
export UV_PYTHON_DOWNLOADS := never
export UV_PROJECT_ENVIRONMENT := $(VENV)
# these machines set PYTHONDONTWRITEBYTECODE=1: without compiled bytecode every import
# compiles from source (import arviz 8.5 s instead of 2.9 s)
export UV_COMPILE_BYTECODE := 1
# numba's on-disk cache for the fused loops lives with the environment
export NUMBA_CACHE_DIR := $(CURDIR)/.cache/numba
export MPLBACKEND := Agg
# test files run in parallel (pytest-xdist), one worker a core; a file's tests stay on one worker
# (its module fixtures are made once): make test TEST_WORKERS=0 runs them one by one
TEST_WORKERS ?= auto
PYTEST_PARALLEL := -n $(TEST_WORKERS) --dist loadfile

.PHONY: env demo test test-load bench bench-load browser clean help

help:  ## list the targets
	@grep -E '^[a-z-]+:.*##' $(MAKEFILE_LIST) | sed 's/:.*## /\t/'

$(VENV)/.synced: pyproject.toml uv.lock
	@$(UV) --version >/dev/null 2>&1 || $(PYTHON) -m pip install --quiet uv
	$(UV) sync --frozen --all-groups
	@touch $@

env: $(VENV)/.synced  ## create or update the environment from uv.lock

demo: env  ## simulate, decode and calibrate on the shipped default scenes; results in runs/demo/
	$(BIN)/feeler demo --out runs/demo --force

browser:  ## headless Chromium for the report rendering test (Debian packages; needs root)
	-@bash .ci/install-browser

test: env browser  ## run the whole test suite (slow suites at a small size), a worker a core
	$(BIN)/python -m pytest $(PYTEST_PARALLEL)

test-load: env browser  ## the whole test suite with two busy-loop processes competing for the cores
	.ci/with-load -n 2 $(BIN)/python -m pytest $(PYTEST_PARALLEL)

bench: env  ## run the benchmarks: medians with spread, idle and under two busy loops; tables in runs/benchmarks/
	@mkdir -p runs/benchmarks
	$(BIN)/python -m pytest benchmarks -p no:cacheprovider --benchmark-json runs/benchmarks/benchmarks.json

bench-load: env  ## every benchmark with two busy-loop processes on the cores (.ci/with-load); tables in runs/benchmarks/load/
	@mkdir -p runs/benchmarks/load
	FEELER_BENCH_UNDER_LOAD=1 .ci/with-load -n 2 $(BIN)/python -m pytest benchmarks -p no:cacheprovider \
		--benchmark-json runs/benchmarks/load/benchmarks.json

clean:  ## remove the environment, caches and generated runs
	rm -rf $(VENV) .cache runs .pytest_cache .benchmarks
