# flowtrack: two set-up commands on a fresh machine.
#   make demo   - the main job (synthetic RGB-D scene -> scene flow -> clusters -> metrics, figures in out/)
#   make test   - the whole test suite (lint, doctests, unit, property and integration tests)
# Both create .venv when needed and install what they need (Debian packages through apt-get;
# sudo is used only when not root).

SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
STAMP := $(VENV)/.flowtrack-installed
# Debian packages the Python stack needs: open3d loads libusb-1.0 and libgomp; scikit-sparse
# (CHOLMOD, the "fast" extra) builds against SuiteSparse.
APT_PACKAGES := libusb-1.0-0 libgomp1 libsuitesparse-dev
OUT ?= out

.PHONY: demo test sysdeps lint bench clean

sysdeps:
	@missing=""; for p in $(APT_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages:$$missing"; \
	  $(SUDO) apt-get update -qq && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq $$missing; \
	fi

$(STAMP): pyproject.toml
	@$(MAKE) --no-print-directory sysdeps
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e ".[dev,lessons,fast]"
	@touch $@

demo: $(STAMP)
	$(VENV)/bin/flowtrack demo --out $(OUT)

test: $(STAMP)
	$(VENV)/bin/ruff check .
	$(PY) -m pytest -n 2 --doctest-modules reference_impl tests

lint: $(STAMP)
	$(VENV)/bin/ruff check .

bench: $(STAMP)
	$(PY) benchmarks/run_all.py

clean:
	rm -rf $(OUT) .pytest_cache .ruff_cache
