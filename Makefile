# inscal — two commands on a fresh machine: `make demo` and `make test`.
PY      ?= python3
VENV    ?= .venv
BIN      = $(VENV)/bin
STAMP    = $(VENV)/.installed-stamp
BSTAMP   = $(VENV)/.bench-stamp
DSTAMP   = $(VENV)/.docs-stamp
WSTAMP   = $(VENV)/.warmup-stamp
# the warm-up's JSON report (tests/cli/test_warmup.py reads it: every kernel compiled in the emptied cache)
WREPORT  = $(VENV)/warmup-report.json
SOURCES := $(shell find src -name '*.py')

.PHONY: demo test bench bench-compare docs venv clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

# the bench extra (filterpy, a benchmark-only dependency) on top of the test install
$(BSTAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[test,bench]'
	touch $(BSTAMP)

# the docs extra (Sphinx, MyST, Furo, sphinx-gallery) on top of the test install
$(DSTAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[test,docs]'
	touch $(DSTAMP)

# an editable install leaves the package as source, and where bytecode may not be written
# (PYTHONDONTWRITEBYTECODE) every `inscal` start compiled its 30,000 lines again (0.3 s): byte-compile
# them here, as a wheel install does.  Python checks each .pyc against its source's time stamp.
# numba compiles a kernel on its first call and keeps it on disk (__pycache__/*.nbi, *.nbc): compile
# them all once after the install, so no command pays it, and again after any source change.  numba
# checks a cached kernel against its own file only, while it holds the code it inlined from kernels of
# other files: a change clears every entry before the warm-up.
$(WSTAMP): $(STAMP) $(SOURCES)
	find src -name '*.nbi' -delete -o -name '*.nbc' -delete
	$(BIN)/python -m compileall -q src
	rm -f $(WREPORT)
	$(BIN)/python -m inscal.cli.warmup --report $(WREPORT)
	touch $(WSTAMP)

venv: $(WSTAMP)

demo: $(WSTAMP)
	$(BIN)/inscal demo --out demo-output --force

# one BLAS thread per test process: the two workers already fill the two cores, and OpenBLAS threads
# spin while they wait (the suite took 20 % longer with them); the longest test files start first
# (tests/conftest.py), so the scopes keep their order instead of xdist's order by number of tests.
# The plugins are named, not found through their packages' entry points: pytest rewrites the asserts of
# every module of a package it found a plugin in (all of hypothesis: 0.6 s per worker), and of the named
# plugin module only.
PLUGINS = -p xdist -p xdist.looponfail -p pytest_postgresql -p hypothesispytest
test: $(WSTAMP)
	$(BIN)/lint-imports
	OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 PYTEST_DISABLE_PLUGIN_AUTOLOAD=1 \
		$(BIN)/python -m pytest -q $(PLUGINS) -n 2 --dist loadfile --no-loadscope-reorder

bench: $(BSTAMP) $(WSTAMP)
	$(BIN)/python bench/run.py

# the benchmarks of revision BASE beside this tree's, alternating, in one run: make bench-compare BASE=main~3
bench-compare: $(BSTAMP) $(WSTAMP)
	$(BIN)/python bench/compare.py --base $(BASE) $(SCRIPTS)

# the documentation site into docs/_build/html, offline, every warning an error (-W, --keep-going to list
# them all), every cross-reference checked (-n), pages read and written by one process per core (-j auto);
# the examples run as the pages build and are kept (docs/auto_examples) until their script changes, so a
# second build runs none of them.  A clean build is about 2 min of CPU (the examples 10 s of it).
docs: $(DSTAMP) $(WSTAMP)
	OPENBLAS_NUM_THREADS=1 $(BIN)/sphinx-build -j auto -W --keep-going -n -q -b html docs docs/_build/html

clean:
	rm -rf $(VENV) demo-output .pytest_cache docs/_build docs/auto_examples docs/reference/api
