# Two commands on a fresh machine: `make demo` and `make test`. Both run `make setup` first.
VENV_BIN := .venv/bin
DEMO_OUT ?= demo_run
export DRJIT_LIBLLVM_PATH ?= $(firstword $(wildcard /usr/lib/x86_64-linux-gnu/libLLVM-19.so /usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 /usr/lib/aarch64-linux-gnu/libLLVM-19.so))
export PYOPENGL_PLATFORM ?= egl

.PHONY: setup demo test bench clean

setup:
	@bash scripts/setup.sh

demo: setup
	$(VENV_BIN)/mna demo -o $(DEMO_OUT)

test: setup
	$(VENV_BIN)/python -m pytest -q -ra tests

bench: setup
	$(VENV_BIN)/python benchmarks/fit_quality.py

clean:
	rm -rf $(DEMO_OUT) .pytest_cache tests/_artifacts
