# vibrospeed: `make demo` and `make test` do all the set-up on a fresh machine.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
OUT ?= demo_out

.PHONY: demo test venv clean bench lint docs

$(BIN)/python:
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@

venv: $(VENV)/.installed

demo: venv
	@mkdir -p $(OUT)
	$(BIN)/vibrospeed simulate --scenario cart --seed 1 --set ticks=on -o $(OUT)/cart.csv
	$(BIN)/vibrospeed truth $(OUT)/cart.csv --from-recording -o $(OUT)/cart_truth.csv
	$(BIN)/vibrospeed estimate $(OUT)/cart.csv --method aided -p omega_min=2 -p omega_max=30 -o $(OUT)/cart_aided.csv --plot $(OUT)/cart_aided.png
	$(BIN)/vibrospeed evaluate $(OUT)/cart_aided.csv --truth $(OUT)/cart_truth.csv --baseline $(OUT)/cart.csv
	$(BIN)/vibrospeed estimate $(OUT)/cart.csv --method ekf --init-omega 10 -o $(OUT)/cart_ekf.csv --plot $(OUT)/cart_ekf.png
	$(BIN)/vibrospeed evaluate $(OUT)/cart_ekf.csv --truth $(OUT)/cart_truth.csv
	$(BIN)/vibrospeed simulate --scenario car --seed 1 -o $(OUT)/car.csv
	$(BIN)/vibrospeed estimate $(OUT)/car.csv --method grid -o $(OUT)/car_grid.csv --plot $(OUT)/car_grid.png
	$(BIN)/vibrospeed evaluate $(OUT)/car_grid.csv --truth $(OUT)/car.csv --baseline $(OUT)/car.csv
	$(BIN)/vibrospeed report $(OUT)/car.csv --estimate $(OUT)/car_grid.csv -o $(OUT)/car_report.html
	$(BIN)/vibrospeed estimate $(OUT)/car.csv --method rbpmf -o $(OUT)/car_rbpmf.csv
	$(BIN)/vibrospeed evaluate $(OUT)/car_rbpmf.csv --truth $(OUT)/car.csv
	$(BIN)/vibrospeed estimate $(OUT)/car.csv --method gps-riss --axis x -o $(OUT)/car_gps.csv
	$(BIN)/vibrospeed evaluate $(OUT)/car_gps.csv --truth $(OUT)/car.csv
	$(BIN)/vibrospeed estimate $(OUT)/car.csv --method algebraic -p L1=1.2 -o $(OUT)/car_algebraic.csv
	$(BIN)/vibrospeed evaluate $(OUT)/car_algebraic.csv --truth $(OUT)/car.csv
	@echo "demo outputs in $(OUT)/: simulated drives, estimates (.csv + .json), plots (.png)"

test: venv
	$(BIN)/python -m pytest -q -n auto --dist loadfile

# the documentation site into site/ (MkDocs, in the test extra); --strict: a warning fails it
docs: venv
	$(BIN)/python -m mkdocs build --strict

bench: venv
	$(BIN)/python benchmarks/ekf_throughput.py

lint: venv
	$(BIN)/python -m ruff --version >/dev/null 2>&1 || $(BIN)/python -m pip install --quiet ruff
	$(BIN)/python -m ruff check .

clean:
	rm -rf $(VENV) $(OUT) build site *.egg-info src/*.egg-info
