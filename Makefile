# vibrospeed: `make demo` and `make test` do all the set-up on a fresh machine.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
OUT ?= demo_out

.PHONY: demo test venv clean bench lint

$(BIN)/python:
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@

venv: $(VENV)/.installed

demo: venv
	@mkdir -p $(OUT)
	$(BIN)/vibrospeed simulate --scenario cart --seed 1 -o $(OUT)/cart.csv
	$(BIN)/vibrospeed estimate $(OUT)/cart.csv --method ekf --init-omega 10 -o $(OUT)/cart_ekf.csv --plot $(OUT)/cart_ekf.png
	$(BIN)/vibrospeed evaluate $(OUT)/cart_ekf.csv --truth $(OUT)/cart.csv
	@echo "demo outputs in $(OUT)/"

test: venv
	$(BIN)/python -m pytest -q

bench: venv
	$(BIN)/python benchmarks/ekf_throughput.py

lint: venv
	$(BIN)/python -m ruff check src tests

clean:
	rm -rf $(VENV) $(OUT) build *.egg-info src/*.egg-info
