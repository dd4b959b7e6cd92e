PYTHON ?= .venv/bin/python

.PHONY: install test lint format bench quickstart docs

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

# the documentation site, warnings as errors (as tests/test_docs_build.py builds it); open docs/_build/html/index.html
docs:
	$(PYTHON) -m sphinx -W --keep-going -b html docs docs/_build/html
