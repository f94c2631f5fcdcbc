# Two commands do everything on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test test-studies venv bench recovery mutation docs docs-fast docs-check clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/stageid demo --out demo-out

# pytest-xdist: two worker processes; an idle worker takes tests from the busy one's queue (worksteal
# ended the suite sooner than one file per worker, tests/TIMING.md). Tests that start servers, clusters
# or a browser take free ports and temporary folders.
test: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks studies
	$(VENV)/bin/ruff format --check src tests benchmarks studies
	$(PY) -m pytest -q -p no:cacheprovider -m "not study" -n 2 --dist worksteal

# The long checks on measured records and randomised draws (marked `study`): CI runs them after
# `make test`, so that the everyday suite stays within a few minutes.
test-studies: $(STAMP)
	$(PY) -m pytest -q -p no:cacheprovider -m study

bench: $(STAMP)
	$(PY) -m pip install --quiet -e '.[bench]'
	$(PY) benchmarks/run_all.py

# The documentation site, built to docs/_build/html with warnings as errors and every reference
# checked (-n); the pages' examples then run as doctests (docstring examples run in the test suite,
# tests/test_docstring_examples.py).  `docs` executes the whole
# gallery; `docs-fast` (CI) a quick subset of it.
DOCS_STAMP := $(VENV)/.installed-docs
SPHINX     := OMP_NUM_THREADS=1 $(PY) -m sphinx -n -W --keep-going

$(DOCS_STAMP): $(STAMP)
	$(PY) -m pip install --quiet -e '.[docs]'
	touch $(DOCS_STAMP)

docs: $(DOCS_STAMP)
	$(SPHINX) -b html docs docs/_build/html
	$(SPHINX) -b doctest -D plot_gallery=0 -d docs/_build/doctrees-doctest docs docs/_build/doctest

docs-fast: $(DOCS_STAMP)
	STAGEID_DOCS_FAST=1 $(SPHINX) -b html docs docs/_build/html
	STAGEID_DOCS_FAST=1 $(SPHINX) -b doctest -D plot_gallery=0 -d docs/_build/doctrees-doctest docs docs/_build/doctest

# CI: the fast site, then the site opened in headless Chromium (no console errors, search finds
# the HankelMAP API page, every gallery image loads).
docs-check: docs-fast
	$(PY) docs/check_site.py docs/_build/html

# Randomised recovery benchmark: every estimator on >= 20 random stages of its own class, fitted
# through the command line; the summary goes to benchmarks/RESULTS-recovery.md (section "Summary").
# RECOVERY_ARGS: more options of benchmarks/recovery/run.py (e.g. --estimators pem,frd --report-only).
RECOVERY_ARGS ?=
recovery: $(STAMP)
	OMP_NUM_THREADS=1 $(PY) benchmarks/recovery/run.py --draws 20 --jobs 2 --out benchmarks/RESULTS-recovery.md $(RECOVERY_ARGS)

# Mutation testing of the estimators' core and the newer tools (cosmic-ray; long, not part of `make test`).
# MUTATION_GROUPS: groups of tests/mutation/run.py (default all); MUTATION_BUDGET: seconds per group.
MUTATION_GROUPS ?=
MUTATION_BUDGET ?= 3600
mutation: $(STAMP)
	$(PY) -m pip install --quiet -e '.[mutation]'
	OMP_NUM_THREADS=1 $(PY) tests/mutation/run.py $(MUTATION_GROUPS) --budget $(MUTATION_BUDGET)

clean:
	rm -rf $(VENV) demo-out build *.egg-info src/*.egg-info docs/_build docs/api docs/auto_examples
