# Every target creates .venv from pinned versions first (Python 3.11 required: bpy 5.0.1).
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
PY := $(VENV)/bin/python
OUT := out

.PHONY: venv render test test-all bench bench-accuracy extension blends references docs-images clean

$(VENV)/.stamp: requirements.txt pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements.txt
	$(PY) -m pip install --quiet --no-deps -e .
	touch $@

venv: $(VENV)/.stamp

# Main job: render an example .blend through the Blender add-on to a PNG.
render: venv
	$(PY) -m addon.batch example_blends/figure6_box.blend -o $(OUT)/figure6_box.png

# Default test run (fast); slow reference renders are marked and run by test-all. The tests
# run in TEST_WORKERS processes (pytest-xdist), a test file each at a time, so a file's
# module fixtures are shared; TEST_WORKERS=0 runs them in this process.
TEST_WORKERS ?= 2
test: venv
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile tests

test-all: venv
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile -m "slow or not slow" tests

bench: venv
	$(PY) bench/bench_core.py

# Error vs time of every setting against Cycles (writes docs/accuracy_time.*, preset labels).
bench-accuracy: venv
	$(PY) bench/bench_accuracy.py

# Cycles reference images for the accuracy tests (tests/references/, a few minutes).
references: venv
	$(PY) tools/make_references.py --samples 2048

# README images: each example blend with and without photon mapping.
docs-images: venv
	$(PY) tools/render_docs_images.py

extension: venv
	$(PY) tools/build_extension.py

blends: venv
	$(PY) example_blends/make_blends.py

clean:
	rm -rf $(VENV) $(OUT) build dist
