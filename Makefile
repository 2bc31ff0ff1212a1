# One way in: `make demo` and `make test` each set up .venv on a fresh machine (idempotent).
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-all sanitize lint type bench clean

$(BIN)/python:
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

# torch first and pinned: a plain `torch` pulled in by stable-baselines3 would fetch GBs of CUDA wheels.
# The install also compiles the sensor kernels (setup.py, src/agrinav_gym/render/csrc): a change there
# reinstalls.
NATIVE := setup.py $(wildcard src/agrinav_gym/render/csrc/*.c src/agrinav_gym/render/csrc/*.h)
$(STAMP): pyproject.toml $(NATIVE) | $(BIN)/python
	$(BIN)/pip install --quiet torch==2.13.0
	$(BIN)/pip install --quiet -e ".[dev]"
	touch $(STAMP)

# The tests also cover the optional extras: Minari recording (jax), Ray shards, the ONNX export
# and GIS field files (pyogrio).
TEST_STAMP := $(VENV)/.installed-test
$(TEST_STAMP): $(STAMP)
	$(BIN)/pip install --quiet -e ".[dev,dataset,ray,export,gis]"
	touch $(TEST_STAMP)

demo: $(STAMP)
	$(BIN)/agrinav demo --out runs/demo

test: $(TEST_STAMP)
	$(BIN)/python -m pytest -n 2 -m "not slow"

test-all: $(TEST_STAMP)
	$(BIN)/python -m pytest -n 2

# The kernels built with AddressSanitizer + UBSan into a temporary folder (the normal build stays)
# and their test files run against that build; any sanitizer report fails (tools/sanitize_kernels.py).
sanitize: $(TEST_STAMP)
	$(BIN)/python tools/sanitize_kernels.py

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/ruff format --check src tests benchmarks

type: $(STAMP)
	$(BIN)/mypy

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_scenario.py
	$(BIN)/python benchmarks/bench_env.py

clean:
	rm -rf $(VENV) runs build *.egg-info src/*.egg-info
