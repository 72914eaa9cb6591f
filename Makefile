# Two entry points for a fresh machine (see README): `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
OUT    ?= out

.PHONY: demo test setup lint typecheck unit bench clean

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

unit: setup
	$(BIN)/pytest -n 2

test: lint typecheck unit

bench: setup
	$(BIN)/python benchmarks/bench_bounds.py
	$(BIN)/python benchmarks/bench_planning.py
	$(BIN)/python benchmarks/bench_api.py

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache .mypy_cache .ruff_cache
