# railtwin: one entry point for humans and CI. Needs only python3 (3.11+), pip and make.
#
#   make test     venv + editable install with test extras, then ruff (check, format --check), mypy, pytest
#   make warm     compile the physics into numba's cache, 2 processes (make venv runs it)
#   make demo     start the twin on loopback, stream a sample train through it, print a line per wheel
#   make bench    run the benchmarks (benchmarks/run_all.py)
#   make bench-reanalyse  re-analyse a generated 10 000-passage archive on 2 Dask workers (minutes)
#   make figures  draw the paper's figures into figures/
#   make soak     20 000-passage burst (memory must plateau), kill -9 mid-stream, recover (minutes)
#   make validate the wheel-flat diagnosis: independent wide set + own generator, railtwin diagnose timed,
#                 then the detector sites' crib channels (~5 min)
#   make validate-track  the discrete/slab track against the independent reference's cases and ROSE (~3 min)
#   make lint     ruff and mypy only
#   make fleet-demo  router, three site twins, the fleet service, a growing flat's alarms (minutes)
#   make fleet-bench the fleet at scale: 100 sites through a router, 10^6 rows, SQLite and PostgreSQL
#
# The venv is (re)installed only when pyproject.toml changes (stamp file); after installing,
# the physics is compiled into numba's cache (`railtwin warm`, its independent parts in
# parallel; a stamp inside the cache, so `make clean` makes the next target warm it again),
# and the first `make demo` or `make test` loads it instead of compiling.

PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
RUNTIME := $(VENV)/.runtime-stamp

# numba's compile cache: inside the (git-ignored) venv so that a read-only
# site-packages or a fresh CI checkout never matters, and runs reuse it.
export NUMBA_CACHE_DIR ?= $(CURDIR)/$(VENV)/numba-cache
WARMED := $(NUMBA_CACHE_DIR)/.warmed-stamp
DEMO_WARMED := $(NUMBA_CACHE_DIR)/.demo-warmed-stamp
# Rerun's CLI asks about analytics on first run; keep CI and tests quiet.
export RERUN_ANALYTICS ?= 0
export PIP_DISABLE_PIP_VERSION_CHECK := 1

.PHONY: help venv warm test lint ruff mypy pytest demo bench bench-reanalyse figures validate validate-track soak clean fleet-demo fleet-bench

help:
	@sed -n '2,15p' Makefile | sed 's/^# \{0,1\}//'

$(BIN)/python:
	$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 11), "railtwin needs Python >= 3.11, got " + sys.version.split()[0]'
	$(PYTHON) -m venv $(VENV)

# (Python 3.11's own pip, 22.3 or later, installs a pyproject.toml project editable: no
# pip upgrade, which cost a round trip to the index and a reinstall on every fresh venv.)
# `make demo` needs only the runtime (RUNTIME, ~40 s on a fresh machine); the test
# extras (ruff, mypy, pytest, pgserver, ...) come on top for everything else (STAMP).
$(RUNTIME): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	touch $(RUNTIME)

$(STAMP): pyproject.toml $(RUNTIME)
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

$(WARMED): $(STAMP)
	$(BIN)/python -m service.cli.warm
	mkdir -p $(NUMBA_CACHE_DIR) && touch $(WARMED)

# make demo's first run compiles only what its site needs (`railtwin warm --only-sites`:
# the constraint's paths on its cosine rail, the track's stepper; not the lumped
# integrator), unless the whole physics is compiled already.
$(DEMO_WARMED): $(RUNTIME)
	@if [ -f $(WARMED) ]; then echo "make demo: the physics is compiled ($(WARMED))"; \
	else $(BIN)/python -m service.cli.warm --site examples/site.toml --only-sites; fi
	mkdir -p $(NUMBA_CACHE_DIR) && touch $(DEMO_WARMED)

venv: $(WARMED)

warm: $(STAMP)
	$(BIN)/python -m service.cli.warm
	mkdir -p $(NUMBA_CACHE_DIR) && touch $(WARMED)

ruff: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

mypy: $(STAMP)
	$(BIN)/mypy

lint: ruff mypy

pytest: $(WARMED)
	$(BIN)/python -m pytest -q

# Runs all three checks even when one fails, then fails if any did.
test: $(WARMED)
	@failed=""; \
	echo "== ruff =="; $(BIN)/ruff check . || failed="$$failed ruff"; \
	echo "== ruff format =="; $(BIN)/ruff format --check . || failed="$$failed ruff-format"; \
	echo "== mypy =="; $(BIN)/mypy || failed="$$failed mypy"; \
	echo "== pytest =="; $(BIN)/python -m pytest -q || failed="$$failed pytest"; \
	if [ -n "$$failed" ]; then echo "make test: FAILED:$$failed" >&2; exit 1; fi; \
	echo "make test: all checks passed"

demo: $(DEMO_WARMED)
	$(BIN)/python -m service.cli demo

bench: $(WARMED)
	$(BIN)/python -m benchmarks.run_all

bench-reanalyse: $(WARMED)
	$(BIN)/python -m benchmarks.dask_bench --archive 10000

fleet-demo: $(WARMED)
	$(BIN)/python -m service.cli.fleet_demo

fleet-bench: $(WARMED)
	$(BIN)/python -m benchmarks.fleet_bench

soak: $(WARMED)
	$(BIN)/python -m benchmarks.soak

validate: $(WARMED)
	nice -n 5 $(BIN)/python -m validation.diagnosis_validation
	nice -n 5 $(BIN)/python -m validation.detector_sites --calibrate

validate-track: $(WARMED)
	nice -n 5 $(BIN)/python -m validation.track_validation --out validation/track_results.md

figures: $(WARMED)
	$(BIN)/python -m service.cli figures --out figures/

clean:
	rm -rf $(VENV)/numba-cache .pytest_cache .mypy_cache .ruff_cache .hypothesis recordings/demo-result.json
