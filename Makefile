# Two entry points for a fresh machine (see README): `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
OUT    ?= out
# Debian's chromium for the browser tests (tests/test_web.py); override for another binary
CHROMIUM ?= /usr/bin/chromium

.PHONY: demo test setup warmup lint typecheck unit portable browser-check bench docs clean

# the install compiles and caches every numba kernel (ris-planner warmup): the first plan
# pays no compilation
$(BIN)/ris-planner: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	$(BIN)/ris-planner warmup
	touch $@

# after editing a kernel (ris_planner/inversion/_crb_jit.py, environment/_jit.py): compile it again now
warmup: setup
	$(BIN)/ris-planner warmup

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

# The suite's verdict must not depend on the CPU (docs/concepts/numerics.md, "Comparing
# results"): the tests of every comparison class – stored files, other processes (REST, CLI,
# worker pools, Dask), iterative solvers, same-process bit-for-bit contracts, ranking – run a
# second time on OpenBLAS's Sandybridge kernels with numpy's AVX-512 dispatch disabled.
PORTABLE_TESTS = tests/test_environment_bounds.py tests/test_beam_design.py tests/test_api.py \
  tests/test_api_plans.py tests/test_api_power.py tests/test_api_geo.py \
  tests/test_planning_executors.py tests/test_planning_shared_memory.py tests/test_power.py \
  tests/test_fast_paths.py tests/test_ldl.py tests/test_crb.py tests/test_fim_naive.py \
  tests/test_ranking.py tests/test_planning.py tests/test_planning_decisions.py \
  tests/test_site_cache_storage.py tests/test_coverage_screen.py tests/test_spherical.py \
  tests/test_planning_physics.py tests/test_planning_rollout.py tests/test_diagnosis.py \
  tests/test_search_quality.py tests/test_api_plan_pool.py tests/test_district.py \
  tests/test_pairs_separation.py tests/test_district_physics.py tests/test_city.py
portable: setup
	OPENBLAS_CORETYPE=Sandybridge \
	NPY_DISABLE_CPU_FEATURES="$$($(BIN)/python tests/avx512_features.py)" \
	$(BIN)/pytest -n 2 -p no:cacheprovider $(PORTABLE_TESTS)

# both halves run whatever the first gives, each reports, and the target fails if either did
# (a failure in the suite on this CPU must not hide what the other kernels give)
test: lint typecheck
	@unit=0; portable=0; \
	$(MAKE) --no-print-directory unit || unit=$$?; \
	$(MAKE) --no-print-directory portable || portable=$$?; \
	echo "make test: unit $$(test $$unit = 0 && echo passed || echo FAILED)," \
	  "portable $$(test $$portable = 0 && echo passed || echo FAILED)"; \
	test $$unit = 0 && test $$portable = 0

# the documentation site (docs/, mkdocs.yml) into site/; warnings are errors. tests/test_docs.py
# builds it too, so `make test` checks it.
docs: setup
	$(BIN)/mkdocs build --strict

# one quick pass over every benchmark area (each script's --quick or --smoke mode, and the asv
# suites once): a check that every benchmark runs, not a measurement (docs/validation/benchmarks.md)
bench: setup
	$(BIN)/python benchmarks/quick.py

clean:
	rm -rf $(VENV) $(OUT) site .pytest_cache .mypy_cache .ruff_cache
