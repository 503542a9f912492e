# cartan — the two commands: `make demo` and `make test`.  Each creates .venv on first use
# (Python >= 3.11 from $(PYTHON)), installs cartan with its extras, then runs.

PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.cartan-installed
BASE   := $(VENV)/.cartan-base
OUT    ?= out
PYTEST_ARGS ?= -n auto --durations=20

.PHONY: install test test-slow test-all demo demo-rigid-body verify verify-full bench lint clean clean-cache help

help:
	@echo "make demo       run the demo scene $(DEMO_SCENE) (writes a netCDF file and a PNG to $(OUT)/)"
	@echo "make demo-rigid-body  free rigid body on SO(3) against its exact Jacobi solution"
	@echo "make test       run the test suite (fast cases; < 10 min)"
	@echo "make test-slow  run the long cases marked 'slow'"
	@echo "make verify     regenerate the verification report docs/verification/ (quick levels)"
	@echo "make bench      run the asv benchmarks once on this machine (offline)"
	@echo "make lint       ruff"

# the package and its run-time dependencies (what `make demo` needs) ...
$(BASE): pyproject.toml Makefile
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else "cartan needs Python >= 3.11; found " + sys.version.split()[0] + " (set PYTHON=python3.11)")'
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e .
	@touch $(BASE)

# ... and the extras of the tests, benchmarks, linting and distributed studies
$(STAMP): $(BASE)
	$(PY) -m pip install --quiet -e ".[test,bench,dev,dist]"
	@touch $(STAMP)

install: $(STAMP)

test: $(STAMP)
	$(PY) -m pytest -m "not slow" $(PYTEST_ARGS)

test-slow: $(STAMP)
	$(PY) -m pytest -m slow $(PYTEST_ARGS)

test-all: $(STAMP)
	$(PY) -m pytest $(PYTEST_ARGS)

DEMO_SCENE ?= rod-cantilever-gravity

# compiled code is built on first use and cached (the first run on a machine says what it compiles)
demo: $(BASE)
	@mkdir -p $(OUT)
	CARTAN_SHOW_COMPILE=1 $(VENV)/bin/cartan run --scene $(DEMO_SCENE) -o $(OUT)/$(DEMO_SCENE).nc
	$(VENV)/bin/cartan plot $(OUT)/$(DEMO_SCENE).nc -o $(OUT)/$(DEMO_SCENE).png

demo-rigid-body: $(BASE)
	$(PY) examples/rigid_body_demo.py --outdir $(OUT)

verify: $(STAMP)
	$(VENV)/bin/cartan verify --quick --out docs/verification

verify-full: $(STAMP)
	$(VENV)/bin/cartan verify --out out/verification

bench: $(STAMP)
	$(VENV)/bin/cartan warm
	$(VENV)/bin/asv machine --yes >/dev/null
	$(VENV)/bin/asv run --python=same --quick --show-stderr

lint: $(STAMP)
	$(VENV)/bin/ruff check cartan plugins tests benchmarks examples

clean:
	rm -rf $(OUT) .asv .pytest_cache .hypothesis

clean-cache:
	find cartan plugins -name '*.nbi' -delete -o -name '*.nbc' -delete
