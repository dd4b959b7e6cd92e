PYTHON ?= .venv/bin/python

.PHONY: install test lint format bench quickstart

install:
	bash scripts/install.sh .venv

test:
	$(PYTHON) -m pytest -q

lint:
	$(PYTHON) -m ruff check .
	$(PYTHON) -m ruff format --check .

format:
	$(PYTHON) -m ruff check --fix .
	$(PYTHON) -m ruff format .

bench:
	$(PYTHON) benchmarks/env_throughput.py
	$(PYTHON) benchmarks/update_speed.py

quickstart:
	bash scripts/quickstart.sh
