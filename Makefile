# Two entry points on a fresh machine: `make demo` (the paper's example end to end)
# and `make test` (the test suite). Both create .venv and install what they need:
# demo the package alone, test (and check) the package with its test extra.
PYTHON ?= python3
PYTHON310 ?= python3.10
VENV := .venv
BIN := $(VENV)/bin
# One stamp per install: the package alone, and the package with the test extra.
STAMP_BASE := $(VENV)/.installed-base
STAMP_TEST := $(VENV)/.installed-test
# The oldest supported Python, in a venv of its own (see test-py310).
VENV310 := .venv310
STAMP_310 := $(VENV310)/.installed-test
# The paths `make check` lints and format-checks.
LINT_PATHS := nrobust tests benchmarks examples
# One BLAS thread: nrobust's linear algebra is small and parallelised by processes;
# threaded OpenBLAS on a busy 2-core machine was measured 4-25x slower.
export OPENBLAS_NUM_THREADS = 1
export OMP_NUM_THREADS = 1
export MPLBACKEND = Agg

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(STAMP_BASE): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	touch $(STAMP_BASE)

# The test extra includes the package, so this install satisfies demo's stamp too.
$(STAMP_TEST): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP_TEST) $(STAMP_BASE)

.PHONY: demo test check fuzz test-py310 bench docs clean
# The package's bytecode, compiled (in nrobust/__pycache__) as installing a wheel does: an editable
# install run with PYTHONDONTWRITEBYTECODE set would compile every module at each start (0.5-1 s).
demo: $(STAMP_BASE)
	$(BIN)/python -m compileall -q nrobust
	$(BIN)/nrobust paper -o out/

# The tests and the doctests of the package (testpaths in pyproject.toml), on every core.
test: $(STAMP_TEST)
	$(BIN)/python -m compileall -q nrobust
	$(BIN)/python -m pytest -q -n auto -m 'not long'

# The differential harness (tests/test_harness.py, tests/test_fuzz_lti.py, tests/test_fuzz_output_feedback.py,
# tests/test_fuzz_design.py) with its long budget (random examples, a 60 s deadline each: about 10 minutes), then
# the long tests (about 2 minutes). Prints cases tried,
# certified claims checked, contradictions (must be 0) and honest refusals; fails on any
# contradiction. `make test` runs the same file on a small fixed budget.
FUZZ_EXAMPLES ?= 500
fuzz: $(STAMP_TEST)
	NROBUST_FUZZ_EXAMPLES=$(FUZZ_EXAMPLES) NROBUST_FUZZ_EXAMPLE_SECONDS=60 \
		$(BIN)/python -m pytest -q -p no:cacheprovider tests/test_harness.py tests/test_fuzz_lti.py \
			tests/test_fuzz_output_feedback.py tests/test_fuzz_design.py
	$(BIN)/python -m pytest -q -p no:cacheprovider -m long tests

# Lint, format and type checks. All three run; the target fails if any failed.
check: $(STAMP_TEST)
	@status=0; \
	echo "== ruff check"; $(BIN)/ruff check $(LINT_PATHS) || status=1; \
	echo "== ruff format --check"; $(BIN)/ruff format --check $(LINT_PATHS) || status=1; \
	echo "== mypy"; $(BIN)/mypy || status=1; \
	exit $$status

# A quick subset of the tests on Python 3.10, the oldest supported version (TOML
# loading there needs tomli, not the standard library's tomllib).
$(STAMP_310): pyproject.toml
	$(PYTHON310) -m venv $(VENV310)
	echo '*' > $(VENV310)/.gitignore
	$(VENV310)/bin/python -m pip install --quiet --upgrade pip
	$(VENV310)/bin/python -m pip install --quiet -e '.[test]'
	touch $(STAMP_310)

test-py310: $(STAMP_310)
	$(VENV310)/bin/python -m pytest -q tests/test_cli.py

# The documentation site into docs/_build/html: the Markdown pages, the API reference from
# the docstrings and the gallery of examples/ (every example runs: about 3 minutes on two
# cores). Warnings are errors, so a broken reference or a malformed docstring fails the build,
# and so does a page that loads a script from the network.
STAMP_DOCS := $(VENV)/.installed-docs
$(STAMP_DOCS): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[docs]'
	touch $(STAMP_DOCS)

docs: $(STAMP_DOCS)
	$(BIN)/sphinx-build -b html -W --keep-going -q docs docs/_build/html
	@# the site loads no script from the network (MathJax is served from _static/mathjax)
	@! grep -rl --include='*.html' '<script[^>]*src="http' docs/_build/html
	@echo "docs/_build/html/index.html"

bench: $(STAMP_TEST)
	$(BIN)/python -m pip install --quiet -e '.[bench]'
	for b in roots kernels margins exact simulate sweep statespace plants imports timeresp design design_local lti paper; do echo "== benchmarks/$$b.py"; $(BIN)/python benchmarks/$$b.py || exit 1; done

clean:
	rm -rf $(VENV) $(VENV310) build *.egg-info .ruff_cache .mypy_cache docs/_build docs/generated docs/auto_examples
	find nrobust tests benchmarks examples -name __pycache__ -type d -prune -exec rm -rf {} +
