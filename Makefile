# Two entry points for a fresh machine (see README): `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
OUT    ?= out
# Debian's chromium for the browser tests (tests/test_web.py); override for another binary
CHROMIUM ?= /usr/bin/chromium

.PHONY: demo test setup lint typecheck unit browser-check bench docs clean

$(BIN)/ris-planner: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $@

setup: $(BIN)/ris-planner

demo: setup
	mkdir -p $(OUT)
	$(BIN)/ris-planner bounds --preset paper-table1 | tee $(OUT)/bounds.json
	$(BIN)/ris-planner plan --preset fig10-anchors --out $(OUT)/plan
	$(BIN)/ris-planner plan --preset hall --out $(OUT)/plan-hall

lint: setup
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

typecheck: setup
	$(BIN)/mypy

# the browser tests need Chromium: say exactly what to install (and fail under CI=true)
browser-check:
	@if [ ! -x "$(CHROMIUM)" ]; then \
	  echo "Chromium not found at $(CHROMIUM): the browser tests (tests/test_web.py) need it."; \
	  echo "  install it with:  apt-get update && apt-get install -y chromium   (as root)"; \
	  echo "  or run:           make test CHROMIUM=/path/to/chromium"; \
	  if [ "$$CI" = "true" ]; then exit 1; fi; \
	  echo "  (outside CI the browser tests are skipped)"; \
	fi

unit: setup browser-check
	RIS_PLANNER_CHROMIUM=$(CHROMIUM) $(BIN)/pytest -n 2 -rs

test: lint typecheck unit

# the documentation site (docs/, mkdocs.yml) into site/; warnings are errors. tests/test_docs.py
# builds it too, so `make test` checks it.
docs: setup
	$(BIN)/mkdocs build --strict

bench: setup
	$(BIN)/python benchmarks/bench_bounds.py
	$(BIN)/python benchmarks/bench_planning.py
	$(BIN)/python benchmarks/bench_api.py

clean:
	rm -rf $(VENV) $(OUT) site .pytest_cache .mypy_cache .ruff_cache
