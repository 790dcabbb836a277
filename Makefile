# Two commands: `make render` and `make test`. Each creates .venv itself.
PYTHON ?= python3.11
VENV   := .venv
PY     := $(VENV)/bin/python
SCENE  ?= examples/whitted_1980.usda
OUT    ?= whitted.png

.PHONY: render test addon wheel bench clean

$(VENV)/.core: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e .
	touch $@

$(VENV)/.test: $(VENV)/.core
	$(PY) -m pip install -q -e ".[test]"
	touch $@

render: $(VENV)/.core
	$(VENV)/bin/whitted render $(SCENE) -o $(OUT)

test: $(VENV)/.test
	$(PY) -m pytest -q

addon: $(VENV)/.test   # Blender's extension builder comes with the bpy wheel (test extra)
	$(PY) -m addon.build dist

wheel: $(VENV)/.core   # a wheel with kernels compiled ahead for the x86-64-v3 baseline (tracer/kernel_bundle.py)
	rm -rf tracer/kernels
	$(PY) -m tracer.kernel_bundle tracer/kernels
	$(PY) -m pip wheel -q --no-deps -w dist .

bench: $(VENV)/.test
	$(PY) -m bench
	$(PY) -m bench.farm

clean:
	rm -rf $(VENV) dist build *.egg-info .pytest_cache tracer/kernels
