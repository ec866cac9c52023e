# The two commands a fresh machine needs: `make run` and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: run test lint bench bench-compare clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[test]"
	touch $(STAMP)

run: $(STAMP)
	$(VENV)/bin/optcal demo

test: $(STAMP)
	$(PY) -m ruff check optcal solvers studies tests
	$(PY) -m pytest

bench: $(STAMP)
	$(PY) -m pytest tests/benchmarks --benchmark-enable --benchmark-only --benchmark-autosave

bench-compare: $(STAMP)
	$(VENV)/bin/pytest-benchmark compare --group-by=name --columns=min,median,mean,stddev $$(ls -t .benchmarks/*/*.json | head -2)

lint: $(STAMP)
	$(PY) -m ruff check optcal solvers studies tests

clean:
	rm -rf $(VENV) build *.egg-info .benchmarks
