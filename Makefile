# flowtrack: two set-up commands on a fresh machine.
#   make demo   - the main job (synthetic RGB-D -> scene flow -> clusters -> tracks -> prediction; out/report.html)
#   make test   - the whole test suite (lint, doctests, unit, property and integration tests)
# Both create .venv when needed and install what they need (Debian packages through apt-get;
# sudo is used only when not root).

SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
STAMP := $(VENV)/.flowtrack-installed
# Debian packages. Core (what `make demo` needs): open3d loads libusb-1.0 and libgomp;
# scikit-sparse (CHOLMOD, the "fast" extra) builds against SuiteSparse.
APT_CORE := libusb-1.0-0 libgomp1 libsuitesparse-dev
# The autograder's sandbox (bubblewrap: namespaces, no network, nothing of the course visible).
APT_GRADER := bubblewrap
# Ports: C++ (Eigen, PCL), Java (EJML, JUnit 5, OpenCV), Octave.
APT_PORTS_CPP := g++ cmake make libeigen3-dev libpcl-dev nlohmann-json3-dev libgtest-dev
APT_PORTS_JVM := openjdk-17-jdk-headless libejml-java junit5 libgoogle-gson-java libopencv-java
APT_PORTS_OCTAVE := octave
# The rendered book and its browser test.
APT_BOOK := chromium chromium-driver
APT_TEST := $(APT_CORE) $(APT_GRADER) $(APT_PORTS_CPP) $(APT_PORTS_JVM) $(APT_PORTS_OCTAVE) $(APT_BOOK)
PIP_EXTRAS := dev,lessons,fast,grading,ports,book
OUT ?= out

.PHONY: demo test sysdeps lint bench book clean

# `make sysdeps APT_PACKAGES="..."` installs the Debian packages that are missing.
APT_PACKAGES ?= $(APT_CORE)
sysdeps:
	@missing=""; for p in $(APT_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages:$$missing"; \
	  $(SUDO) apt-get update -qq && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq $$missing; \
	fi

$(STAMP): pyproject.toml
	@$(MAKE) --no-print-directory sysdeps APT_PACKAGES="$(APT_CORE)"
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e ".[$(PIP_EXTRAS)]"
	@touch $@

demo: $(STAMP)
	$(VENV)/bin/flowtrack demo --out $(OUT)

test: $(STAMP)
	@$(MAKE) --no-print-directory sysdeps APT_PACKAGES="$(APT_TEST)"
	$(VENV)/bin/ruff check .
	$(PY) -m pytest -n 2 --dist loadgroup --doctest-modules reference_impl tests

lint: $(STAMP)
	$(VENV)/bin/ruff check .

bench: $(STAMP)
	$(PY) benchmarks/run_all.py

# The lessons and solutions, executed, as a static site that reads offline: open $(OUT)/book/index.html
book: $(STAMP)
	$(PY) -m flowtrack_course.book --out $(OUT)/book

clean:
	rm -rf $(OUT) .pytest_cache .ruff_cache
