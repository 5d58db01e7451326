# dancedata — every target installs into .venv first if needed.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
DEMO_RAW := data/raw/aist-demo
DEMO_STORE := data/stores/aist-demo
DEMO_SEQUENCES ?= 24

.PHONY: install pipeline test lint bench clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

install: $(STAMP)

pipeline: $(STAMP)
	test -d $(DEMO_RAW) || $(BIN)/dancedata synth aist $(DEMO_RAW) --sequences $(DEMO_SEQUENCES) --seed 0
	$(BIN)/dancedata ingest aist $(DEMO_RAW) --store $(DEMO_STORE)
	$(BIN)/dancedata featurize $(DEMO_STORE)
	$(BIN)/dancedata segment $(DEMO_STORE)
	$(BIN)/dancedata validate $(DEMO_STORE)
	$(BIN)/dancedata info $(DEMO_STORE)

test: $(STAMP)
	$(PY) -m pytest -q

bench: $(STAMP)
	$(PY) bench/run.py $(BENCH)

lint: $(STAMP)
	$(BIN)/ruff check .

clean:
	rm -rf data/raw data/stores .pytest_cache
