# Two commands on a fresh machine:  `make demo` (the main job) and `make test` (the tests).
# Both create .venv and install the project into it first; nothing is installed by hand.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test check bench install clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/hrc demo

test: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -q

check: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -q -m "not cell"

bench: $(STAMP)
	$(BIN)/python bench/scaling.py
	$(BIN)/python bench/planning.py
	$(BIN)/python bench/can_loop.py
	$(BIN)/python bench/end_to_end.py
	$(BIN)/python bench/cell_cpu.py
	$(BIN)/python bench/compare.py
	$(BIN)/python bench/forecast.py

clean:
	rm -rf $(VENV) build *.egg-info .numba-cache
