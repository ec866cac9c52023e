# The two commands a fresh machine needs: `make run` and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
RUN_STAMP := $(VENV)/.installed-run
STAMP  := $(VENV)/.installed
# Monte-Carlo runs of `make run`: the headline study's configurations, all of them, on 20 of its 50 runs, so
# that a fresh clone shows the table within 8 minutes on two cores (docs/performance.md, "The time of `make
# run`"); `make run-full` runs all 50.
RUNS   ?= 20

.PHONY: run run-full run-quick test docs lint bench bench-compare clean

# What the study needs (optcal, nevergrad for the ng: solvers, mealpy for mealpy:), then the evaluation kernels
# compiled once (numba caches them; the time is printed).
$(RUN_STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[nevergrad]"
	$(PY) -m pip install --quiet --no-deps $$($(PY) -c "import sys; t = __import__('tomllib' if sys.version_info >= (3, 11) else 'tomli'); print(' '.join(t.load(open('pyproject.toml', 'rb'))['tool']['optcal']['install-without-deps']))")
	$(PY) -m optcal.core.warmup
	touch $(RUN_STAMP)

# The tests' and the documentation's tools on top.
$(STAMP): $(RUN_STAMP)
	$(PY) -m pip install --quiet -e ".[test]"
	touch $(STAMP)

# The headline comparison study (optcal/studies/specs/compare.toml: 41 configurations × 2 models × 2 schemes) on
# $(RUNS) Monte-Carlo runs (3,280 trials) and its report, out/compare/report.md, on every core; the report's
# headline tables are written after the first run and refreshed while it goes. A study that is stopped resumes
# where it stopped when run again. `make run-full`: the spec's 50 runs (8,200 trials; the README's table) into
# out/compare-full; `make run-quick`: its 10-run variant.
run: $(RUN_STAMP)
	$(VENV)/bin/optcal study run compare --runs $(RUNS) --executor processes \
		--workers $$(nproc 2>/dev/null || echo 2) --out out/compare

run-full: $(RUN_STAMP)
	$(VENV)/bin/optcal study run compare --executor processes --workers $$(nproc 2>/dev/null || echo 2) \
		--out out/compare-full

run-quick: $(RUN_STAMP)
	$(VENV)/bin/optcal study run compare --quick --executor processes --workers $$(nproc 2>/dev/null || echo 2) \
		--out out/compare-quick

# ruff, then the layer contracts of pyproject.toml (CONTRIBUTING.md, "Layers"), then the tests on every core
# (pytest-xdist; a worker that finishes early takes work from the other).
test: $(STAMP)
	$(PY) -m ruff check optcal tests
	$(VENV)/bin/lint-imports --no-cache
	$(MAKE) --no-print-directory docs
	$(PY) -m pytest -n auto --dist worksteal

# The documentation site (mkdocs.yml) into build/site/: --strict fails on every warning (a missing page or anchor, a
# page left out of the nav, a docstring the API reference cannot render). Not --quiet, which hides the warnings
# from the strict check too. NO_MKDOCS_2_WARNING silences mkdocs-material's banner about its successor.
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict

bench: $(STAMP)
	$(PY) -m pytest tests/benchmarks --benchmark-enable --benchmark-only --benchmark-autosave

# The latest saved benchmark run against the one before it (both saved by `make bench`).
bench-compare: $(STAMP)
	@runs="$$(ls -t .benchmarks/*/*.json 2>/dev/null | head -2 | tac)"; \
	if [ "$$(echo "$$runs" | grep -c json)" -lt 2 ]; then \
		echo "make bench-compare needs two saved runs in .benchmarks/: run make bench twice"; exit 1; fi; \
	$(VENV)/bin/pytest-benchmark compare --group-by=name --columns=min,median,mean,stddev $$runs

lint: $(STAMP)
	$(PY) -m ruff check optcal tests

clean:
	rm -rf $(VENV) build *.egg-info .benchmarks
