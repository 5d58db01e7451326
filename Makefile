# dancedata — every target installs into .venv first if needed.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
BIN := $(VENV)/bin
# Stamps: .installed = dancedata and its required dependencies only (what `make pipeline`
# needs, with the viz stamp); .installed-dev = the 'dev' extra (pytest, ruff, hypothesis, and the
# scale/S3 stack the tests use), for test, lint, fuzz and bench.
STAMP := $(VENV)/.installed
DEV_STAMP := $(VENV)/.installed-dev
# The optional OpenUnmix stack (the 'stems' extra), pinned to builds that load together; `make
# test` installs it once (its own stamp) so tests/compute/test_stems_openunmix.py runs instead of skipping.
STEMS_STAMP := $(VENV)/.installed-stems
STEMS_PINS ?= torch==2.14.1 torchaudio==2.11.0 openunmix==1.3.0
# An extra package index for the stems stack, e.g. PyTorch's CPU-only builds on a machine without
# a GPU: make test TORCH_INDEX=https://download.pytorch.org/whl/cpu (PyPI's torch brings ~4 GB of
# CUDA libraries; the CPU build's local version, 2.14.1+cpu, sorts above 2.14.1, so pip takes it).
TORCH_INDEX ?=
# The 'viz' extra (matplotlib, PyAV) for plot/report/render: `make pipeline` and `make test`.
VIZ_STAMP := $(VENV)/.installed-viz
# setuptools warns on every editable build ("Editable installation ... folders with the same
# name as your package"): shown by the first install, silenced for the extras' re-installs.
QUIET_EDITABLE := PYTHONWARNINGS="ignore:Editable installation"
# Headless Chromium (Debian package) renders the report page in tests and for README stills.
CHROMIUM := /usr/bin/chromium
DEMO_RAW := data/raw/aist-demo
DEMO_STORE := data/stores/aist-demo
DEMO_SEQUENCES ?= 24
DEMO_REPORT := data/stores/aist-demo-report.html
DEMO_PLOT := data/stores/aist-demo-plot.png
DEMO_RENDER := data/stores/aist-demo-render.mp4
# The demo experiment (experiments/demo.toml): results.parquet + results.json.
DEMO_RESULTS := data/stores/aist-demo-experiment
# The sequence drawn for docs/img/plot.png (default: the store's first, looked up at run time).
DEMO_PLOT_SEQ ?= $$($(PY) -c "import dancedata; print(dancedata.open_store('$(DEMO_STORE)').seq_ids()[0])")

.PHONY: install install-dev install-stems install-viz browser pipeline test test-fast lint bench fuzz clean schema

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e .
	touch $(STAMP)

install: $(STAMP)

$(DEV_STAMP): $(STAMP)
	$(QUIET_EDITABLE) $(PY) -m pip install --quiet -e '.[dev]'
	touch $(DEV_STAMP)

install-dev: $(DEV_STAMP)

$(STEMS_STAMP): $(DEV_STAMP)
	$(QUIET_EDITABLE) $(PY) -m pip install --quiet -e '.[dev,stems]' $(STEMS_PINS) \
		$(if $(TORCH_INDEX),--extra-index-url $(TORCH_INDEX))
	touch $(STEMS_STAMP)

install-stems: $(STEMS_STAMP)

$(VIZ_STAMP): $(STAMP)
	$(QUIET_EDITABLE) $(PY) -m pip install --quiet -e '.[viz]'
	touch $(VIZ_STAMP)

install-viz: $(VIZ_STAMP)

# Debian's chromium, only when no chromium is installed (needs root, as on CI), without the
# recommended packages (with them, ~120 packages and upgrades of systemd and perl).
browser:
	test -x $(CHROMIUM) || command -v chromium >/dev/null || (apt-get update && \
		DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends chromium)

pipeline: $(STAMP) $(VIZ_STAMP)
	test -d $(DEMO_RAW) || $(BIN)/dancedata synth aist $(DEMO_RAW) --sequences $(DEMO_SEQUENCES) --seed 0
	$(BIN)/dancedata ingest aist $(DEMO_RAW) --store $(DEMO_STORE)
	$(BIN)/dancedata featurize $(DEMO_STORE)
	$(BIN)/dancedata segment $(DEMO_STORE)
	$(BIN)/dancedata validate $(DEMO_STORE)
	$(BIN)/dancedata info $(DEMO_STORE)
	$(BIN)/dancedata report $(DEMO_STORE) $(DEMO_REPORT)
	$(BIN)/dancedata plot $(DEMO_STORE) $(DEMO_PLOT_SEQ) $(DEMO_PLOT)
	mkdir -p docs/img
	cp $(DEMO_PLOT) docs/img/plot.png
	$(BIN)/dancedata render $(DEMO_STORE) $(DEMO_PLOT_SEQ) $(DEMO_RENDER)
	$(BIN)/dancedata render $(DEMO_STORE) $(DEMO_PLOT_SEQ) docs/img/render.png --start 240
	if test -x $(CHROMIUM); then $(CHROMIUM) --headless --no-sandbox --disable-gpu --hide-scrollbars \
		--window-size=1280,900 --screenshot=docs/img/report.png file://$(abspath $(DEMO_REPORT)) 2>/dev/null; \
	else echo "no $(CHROMIUM): report still not refreshed (make browser installs it)"; fi
	$(BIN)/dancedata experiment run experiments/demo.toml --store $(DEMO_STORE) --out $(DEMO_RESULTS)
	$(BIN)/dancedata experiment table demo --results $(DEMO_RESULTS)

# Tests use a temporary feature cache (tests/conftest.py sets DANCEDATA_CACHE), never ~/.cache.
# pytest-xdist runs them on PYTEST_WORKERS processes (auto: one per core), each taking whole
# test files (--dist loadfile), so a module's store fixture is built once, not once per worker.
# Each worker's numba folder starts as a copy of the machine's cache (what `make pipeline`, any
# `dancedata featurize` or `dancedata cache warm` compiled). `make test` does not warm it
# itself: measured on a new machine, the warm-up's 36 s (one core) bought 29 s of tests, because
# without it the two workers compile side by side; run in the background while pip installed the
# extras, it slowed the installs by ~20 s and the tests were no faster (bench/RESULTS.md, 2026-12-08).
PYTEST_WORKERS ?= auto
PYTEST_PARALLEL = -n $(PYTEST_WORKERS) --dist loadfile
test: $(DEV_STAMP) $(STEMS_STAMP) $(VIZ_STAMP) browser
	$(PY) -m pytest -q $(PYTEST_PARALLEL)

# The tests not marked slow (subprocess kills, S3, Dask, rendering, OpenUnmix, whole-store runs):
# the run to repeat while working, under two minutes on two cores.
test-fast: $(DEV_STAMP) $(STEMS_STAMP) $(VIZ_STAMP)
	$(PY) -m pytest -q $(PYTEST_PARALLEL) -m "not slow"

# bench_batching.py needs torch: the stems stamp installs the pinned torch build.
bench: $(DEV_STAMP) $(VIZ_STAMP) $(STEMS_STAMP)
	$(PY) bench/run.py $(BENCH)

# Hypothesis fuzzing of the readers (fuzz/run.py): FUZZ_MINUTES of examples, then statistics.
FUZZ_MINUTES ?= 10
fuzz: $(DEV_STAMP)
	$(PY) fuzz/run.py --minutes $(FUZZ_MINUTES) $(FUZZ_ARGS)

# ruff on the whole tree; mypy (settings in pyproject.toml) on the packages of MYPY_PATHS, which
# grows as packages are made clean (tests/project/test_tooling.py checks that the mypy hook of
# .pre-commit-config.yaml lists the same). The stems stamp installs torch, which the checked code
# imports.
MYPY_PATHS := dancedata/io dancedata/compute dancedata/ops dancedata/store
lint: $(DEV_STAMP) $(STEMS_STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy $(MYPY_PATHS)

# The arrays and extension_arrays of schemas/store.schema.json, from the arrays the code declares
# (tests/featurize/test_family_framework.py fails when the committed file differs).
schema: $(STAMP)
	$(PY) -m dancedata.featurize.schema_arrays

clean:
	rm -rf data/raw data/stores .pytest_cache
