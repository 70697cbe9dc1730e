# Two commands do everything on a fresh machine (README):  make run   and   make test
# Both create .venv on first use and install the package with its dependencies into it.
# constraints.txt pins torch to a release that this project's machines carry as a CPU build;
# elsewhere pip takes the usual build for that release (CUDA on Linux). CONSTRAINTS= drops the pin.

PYTHON ?= python3
VENV ?= .venv
CONSTRAINTS ?= constraints.txt
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: run test test-all lint bench clean clean-cache

$(STAMP): pyproject.toml $(CONSTRAINTS)
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet $(if $(CONSTRAINTS),-c $(CONSTRAINTS)) -e ".[dev,tune]"
	touch $(STAMP)

run: $(STAMP)  ## the main job: agents compared on FanTracking (configs/fan_tracking.yaml)
	$(VENV)/bin/quad-wrench demo

test: $(STAMP)  ## the fast test suite (what CI runs)
	$(PY) -m pytest -q

test-all: $(STAMP)  ## every test, the slow ones included
	$(PY) -m pytest -q -m "slow or not slow"

lint: $(STAMP)
	$(VENV)/bin/ruff check . && $(VENV)/bin/ruff format --check .

bench: $(STAMP)
	$(VENV)/bin/quad-wrench bench

clean:
	rm -rf $(VENV) results

clean-cache:  ## numba's disk caches and the composed steps (after editing a kernel that others call)
	find quad_wrench_env tests -name '*.nbi' -delete -o -name '*.nbc' -delete
	rm -rf "$${QUAD_WRENCH_CACHE_DIR:-$${XDG_CACHE_HOME:-$$HOME/.cache}/quad_wrench_env}"
