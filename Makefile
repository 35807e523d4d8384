# Every target creates .venv from pinned versions first (Python 3.11 required: bpy 5.0.1).
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
OUT := out

.PHONY: venv render test test-all bench extension blends references clean

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
	@echo "wrote $(OUT)/figure6_box.png"

# Default test run (fast); slow reference renders are marked and run by test-all.
test: venv
	$(PY) -m pytest -q tests

test-all: venv
	$(PY) -m pytest -q -m "slow or not slow" tests

bench: venv
	$(PY) bench/bench_core.py

extension: venv
	$(PY) tools/build_extension.py

blends: venv
	$(PY) example_blends/make_blends.py

clean:
	rm -rf $(VENV) $(OUT) build dist
