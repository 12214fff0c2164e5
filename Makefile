# The two entry points a newcomer needs: `make demo` and `make test`.
#   make demo          the quick reproduction of the paper (about a minute after installation)
#   make demo FULL=1   the full reproduction (all DistMesh runs, six repeats: several minutes more)
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
PIP := $(BIN)/python -m pip --disable-pip-version-check
FULL ?=
PAPER_FLAGS := $(if $(FULL),,--quick)

.PHONY: demo test lint bench clean

$(BIN)/python:
	@echo "make: creating $(VENV) with $(PYTHON)"
	$(PYTHON) -m venv $(VENV)
	@# Editable installs from pyproject.toml need pip >= 21.3; upgrade only an older one.
	@$(BIN)/python -c "import pip, sys; sys.exit(tuple(map(int, pip.__version__.split('.')[:2])) < (21, 3))" \
		|| $(PIP) install --quiet --upgrade pip

# The demo needs the runtime extras only (plots and mesh files), not the test toolchain.
$(VENV)/.runtime: pyproject.toml | $(BIN)/python
	@echo "make: installing injmesh with numpy, scipy, matplotlib and meshio"
	$(PIP) install --progress-bar on -e ".[plot,io]"
	touch $@

$(VENV)/.test: pyproject.toml | $(BIN)/python
	@echo "make: installing injmesh with its test extras (pytest, hypothesis, ruff, mypy, scikit-fem)"
	$(PIP) install --progress-bar on -e ".[test]"
	touch $@ $(VENV)/.runtime

demo: $(VENV)/.runtime
	$(BIN)/injmesh paper $(PAPER_FLAGS) --out paper-results

test: $(VENV)/.test
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/mypy
	$(BIN)/pytest -q

lint: $(VENV)/.test
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/mypy

bench: $(VENV)/.runtime
	$(BIN)/python benchmarks/paper_cases.py

clean:
	rm -rf $(VENV) paper-results .pytest_cache .mypy_cache .ruff_cache
