# One-command set-up: every target creates .venv and installs the project itself.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: run test lint table bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip==25.3
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

run: $(STAMP)
	$(PY) -m controller.closed_loop --example 1 --mode fixed-time

test: $(STAMP)
	$(PY) -m pytest -q -n 2

lint: $(STAMP)
	$(VENV)/bin/ruff check .

table: $(STAMP)
	$(PY) -m controller.closed_loop --table

bench: $(STAMP)
	$(PY) benchmarks/controller_step.py

clean:
	rm -rf build results
