# SSS Lab: `make demo` runs the main job on the sample scene, `make test` runs lint and tests.
# Each target sets up .venv by itself (tools/bootstrap.sh) on a fresh machine.
PY := .venv/bin/python
OUT ?= out

.PHONY: venv demo test lint format bench extension clean

venv:
	@bash tools/bootstrap.sh

demo: venv
	$(PY) -m sss_lab demo --out $(OUT)

test: venv
	$(PY) -m ruff check .
	$(PY) -m ruff format --check .
	@bash tools/ensure_chromium.sh
	$(PY) -m pytest tests

lint: venv
	$(PY) -m ruff check .
	$(PY) -m ruff format --check .

format: venv
	$(PY) -m ruff format .
	$(PY) -m ruff check --fix .

bench: venv
	$(PY) -m benchmarks.speed

extension: venv
	$(PY) tools/build_extension.py

clean:
	rm -rf dist wheels $(OUT)
