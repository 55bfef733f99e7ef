# uav-energy: every target bootstraps its own virtual environment from pyproject.toml.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint bench fit-real figures figures-check clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/uav-energy demo

test: $(STAMP)
	$(BIN)/ruff check estimator tests bench scripts
	$(BIN)/ruff format --check estimator tests bench scripts
	$(BIN)/mypy
	$(BIN)/pytest -q

fit-real: $(STAMP)
	scripts/fit_real.sh ../shared/data

bench: $(STAMP)
	$(BIN)/python -m bench

# The result figures of README.md and docs/*.md: rewrite their blocks, or check them.
figures: $(STAMP)
	$(BIN)/python scripts/figures.py

figures-check: $(STAMP)
	$(BIN)/python scripts/figures.py --check

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache
