# `make demo` and `make test` work on a fresh Debian machine with only Python installed:
# the first run installs the system packages it needs (when it can), creates .venv and installs
# the project with its development tools.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
SUDO   := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

.PHONY: demo test lint bench system-deps clean

demo: $(STAMP)
	$(BIN)/grace demo

test: $(STAMP)
	$(BIN)/python -m pytest

lint: $(STAMP)
	$(BIN)/ruff check grace_dsl tests bench
	$(BIN)/mypy grace_dsl/lang grace_dsl/compiler

bench: $(STAMP)
	$(BIN)/python bench/bench_eval.py

# venv support and a C compiler (the compiler turns concepts into native code when one exists).
system-deps:
	@if ! $(PYTHON) -c 'import ensurepip, venv' >/dev/null 2>&1 || ! command -v cc >/dev/null 2>&1; then \
	  if command -v apt-get >/dev/null 2>&1; then \
	    echo "installing system packages: python3-venv gcc"; \
	    $(SUDO) apt-get update -qq && \
	    $(SUDO) env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv gcc libc6-dev; \
	  else \
	    echo "warning: no apt-get; make sure Python's venv module and a C compiler are installed"; \
	  fi; \
	fi

$(STAMP): pyproject.toml
	@$(MAKE) --no-print-directory system-deps
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev,sim]'
	@touch $(STAMP)

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .mypy_cache .ruff_cache
