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

# The headline comparison study (studies/specs/compare.toml) and its report, out/compare-quick/report.md.
# The full study (50 runs) takes longer than 15 minutes on 2 cores (docs/studies.md), so `make run` runs
# its --quick variant; the full one: .venv/bin/optcal study run compare  (report: out/compare/report.md).
# A study that is stopped resumes where it stopped when run again.
run: $(STAMP)
	$(VENV)/bin/optcal study run compare --quick --executor processes --workers $$(nproc 2>/dev/null || echo 2) \
		--out out/compare-quick

test: $(STAMP)
	$(PY) -m ruff check optcal solvers studies tests
	$(PY) -m pytest

bench: $(STAMP)
	$(PY) -m pytest tests/benchmarks --benchmark-enable --benchmark-only --benchmark-autosave

# The latest saved benchmark run against the one before it (both saved by `make bench`).
bench-compare: $(STAMP)
	@runs="$$(ls -t .benchmarks/*/*.json 2>/dev/null | head -2 | tac)"; \
	if [ "$$(echo "$$runs" | grep -c json)" -lt 2 ]; then \
		echo "make bench-compare needs two saved runs in .benchmarks/: run make bench twice"; exit 1; fi; \
	$(VENV)/bin/pytest-benchmark compare --group-by=name --columns=min,median,mean,stddev $$runs

lint: $(STAMP)
	$(PY) -m ruff check optcal solvers studies tests

clean:
	rm -rf $(VENV) build *.egg-info .benchmarks
