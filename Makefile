# clsas: the commands the README gives (make demo, make test) and the ones behind them.
# `setup` is idempotent: it creates .venv, installs clsas editable with its test and plot
# extras, and installs Debian's PoCL CPU driver when pyopencl sees no OpenCL platform.

PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.clsas-installed

.PHONY: setup opencl demo test test-all bench clean

setup: $(STAMP) opencl

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test,plot]'
	touch $(STAMP)

# Install PoCL (CPU OpenCL driver) from Debian only when no OpenCL device is visible.
opencl: $(STAMP)
	@if $(PY) -c "import pyopencl as cl, sys; sys.exit(0 if any(p.get_devices() for p in cl.get_platforms()) else 1)" 2>/dev/null; then \
	    echo "OpenCL device found"; \
	else \
	    echo "no OpenCL platform visible: installing Debian's pocl-opencl-icd"; \
	    SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	    $$SUDO apt-get update -qq && \
	    DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq pocl-opencl-icd ocl-icd-libopencl1 clinfo >/dev/null && \
	    $(PY) -c "import pyopencl as cl; print('OpenCL:', [d.name for p in cl.get_platforms() for d in p.get_devices()])"; \
	fi

demo: setup
	$(PY) -m clsas demo

test: setup
	CLSAS_REQUIRE_OPENCL=1 $(PY) -m pytest -m "not slow" tests

test-all: setup
	CLSAS_REQUIRE_OPENCL=1 $(PY) -m pytest tests

bench: setup
	$(PY) bench/run_all.py

clean:
	rm -rf $(VENV) build dist .pytest_cache
