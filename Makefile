# dancedata — every target installs into .venv first if needed.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# The optional OpenUnmix stack (the 'stems' extra), pinned to builds that load together; `make
# test` installs it once (its own stamp) so tests/test_stems_openunmix.py runs instead of skipping.
STEMS_STAMP := $(VENV)/.installed-stems
STEMS_PINS ?= torch==2.14.1 torchaudio==2.11.0 openunmix==1.3.0
DEMO_RAW := data/raw/aist-demo
DEMO_STORE := data/stores/aist-demo
DEMO_SEQUENCES ?= 24

.PHONY: install install-stems pipeline test lint bench fuzz clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

install: $(STAMP)

$(STEMS_STAMP): $(STAMP)
	$(PY) -m pip install --quiet -e '.[dev,stems]' $(STEMS_PINS)
	touch $(STEMS_STAMP)

install-stems: $(STEMS_STAMP)

pipeline: $(STAMP)
	test -d $(DEMO_RAW) || $(BIN)/dancedata synth aist $(DEMO_RAW) --sequences $(DEMO_SEQUENCES) --seed 0
	$(BIN)/dancedata ingest aist $(DEMO_RAW) --store $(DEMO_STORE)
	$(BIN)/dancedata featurize $(DEMO_STORE)
	$(BIN)/dancedata segment $(DEMO_STORE)
	$(BIN)/dancedata validate $(DEMO_STORE)
	$(BIN)/dancedata info $(DEMO_STORE)

# Tests use a temporary feature cache (tests/conftest.py sets DANCEDATA_CACHE), never ~/.cache.
test: $(STEMS_STAMP)
	$(PY) -m pytest -q

bench: $(STAMP)
	$(PY) bench/run.py $(BENCH)

# Hypothesis fuzzing of the readers (fuzz/run.py): FUZZ_MINUTES of examples, then statistics.
FUZZ_MINUTES ?= 10
fuzz: $(STAMP)
	$(PY) fuzz/run.py --minutes $(FUZZ_MINUTES) $(FUZZ_ARGS)

lint: $(STAMP)
	$(BIN)/ruff check .

clean:
	rm -rf data/raw data/stores .pytest_cache
