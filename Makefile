# `make demo` and `make test` work on a fresh Debian machine with only Python installed:
# the first run installs the system packages it needs (when it can), creates .venv and installs
# the project with its development tools.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
SUDO   := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

.PHONY: demo test test-fast lint bench bench-smoke verify gallery system-deps clean

demo: $(STAMP)
	$(BIN)/grace demo

# one pytest-xdist worker per core; a worker that runs dry steals half of another's queue, so
# the minute-long tests do not leave a core idle at the end (docs/benchmarks.md, Test suite time)
PYTEST := $(BIN)/python -m pytest -n auto --dist worksteal

test: $(STAMP)
	$(PYTEST)

# the local loop: every test not marked slow (> ~3 s; pyproject.toml lists the markers), with
# the standard library's build kept between runs (a private per-user test cache)
test-fast: $(STAMP)
	$(PYTEST) -m "not slow" --reuse-build-cache

lint: $(STAMP)
	$(BIN)/ruff check grace_dsl tests bench
	$(BIN)/mypy grace_dsl

bench: $(STAMP)
	$(BIN)/python bench/bench_eval.py

# every bench/ script at a tiny size (tests/bench): does each still run?
bench-smoke: $(STAMP)
	$(PYTEST) -m bench tests/bench

# every concept of the standard library, 200 random draws each (docs/benchmarks.md, verification)
verify: $(STAMP)
	$(BIN)/python bench/bench_verify.py

# docs/gallery: a picture of every concept of the standard library and every primitive
gallery: $(STAMP)
	$(BIN)/eacc gallery -o docs/gallery

# venv support and a C compiler (the compiler turns concepts into native code when one exists);
# OSMesa for headless MuJoCo pictures (eacc show --png) and Chromium for the HTML viewer's tests;
# libX11, which SAPIEN's library links even when its physics runs alone (Chromium brings it too).
system-deps:
	@missing=""; \
	if ! $(PYTHON) -c 'import ensurepip, venv' >/dev/null 2>&1 || ! command -v cc >/dev/null 2>&1; then \
	  missing="python3-venv gcc libc6-dev"; \
	fi; \
	if ! $(PYTHON) -c 'import ctypes.util as u, sys; sys.exit(not u.find_library("OSMesa"))'; then \
	  missing="$$missing libosmesa6"; \
	fi; \
	if ! command -v chromium >/dev/null 2>&1; then missing="$$missing chromium"; fi; \
	if ! $(PYTHON) -c 'import ctypes.util as u, sys; sys.exit(not u.find_library("X11"))'; then \
	  missing="$$missing libx11-6"; \
	fi; \
	if [ -n "$$missing" ]; then \
	  if command -v apt-get >/dev/null 2>&1; then \
	    echo "installing system packages:$$missing"; \
	    $(SUDO) apt-get update -qq && \
	    $(SUDO) env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing; \
	  else \
	    echo "warning: no apt-get; install:$$missing (venv, C compiler, OSMesa, Chromium)"; \
	  fi; \
	fi

$(STAMP): pyproject.toml
	@$(MAKE) --no-print-directory system-deps
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev,sim,plan,learn,ray,vlm,sapien]'
	@touch $(STAMP)

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .mypy_cache .ruff_cache
