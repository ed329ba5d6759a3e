# Two commands on a fresh machine: `make demo` and `make test`. Both run `make setup` first.
VENV_BIN := .venv/bin
DEMO_OUT ?= demo_run
export PYOPENGL_PLATFORM ?= egl

.PHONY: setup lint demo test bench bench-fit bench-atlas bench-render bench-train bench-paper clean

setup:
	@bash scripts/setup.sh

demo: setup
	$(VENV_BIN)/mna demo -o $(DEMO_OUT) --overwrite

test: setup lint
	$(VENV_BIN)/python -m pytest -q -ra tests

lint: setup
	$(VENV_BIN)/ruff check .

# Benchmarks (long; results go to benchmarks/RESULTS.md). Not part of `make test`.
bench: bench-fit bench-atlas bench-render bench-train bench-paper

bench-fit: setup
	$(VENV_BIN)/python benchmarks/fit_quality.py

bench-atlas: setup
	$(VENV_BIN)/python benchmarks/atlas_vs_xatlas.py

bench-render: setup
	$(VENV_BIN)/python benchmarks/render.py

bench-train: setup
	$(VENV_BIN)/python benchmarks/train_throughput.py

# The paper's claims at our scale (issue 19): about an hour or two on 2 CPU cores.
bench-paper: setup
	$(VENV_BIN)/python benchmarks/paper_tables.py

clean:
	rm -rf $(DEMO_OUT) .pytest_cache tests/_artifacts
