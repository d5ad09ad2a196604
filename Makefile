# clsas: the commands the README gives (make demo, make test) and the ones behind them.
# `setup` is idempotent: it creates .venv, installs clsas editable with its test and plot
# extras, and installs Debian's PoCL CPU driver when pyopencl sees no OpenCL platform.

PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.clsas-installed
BUILT  := $(VENV)/.clsas-kernels-built

.PHONY: setup opencl setup-pip-opencl demo test test-all bench clean

setup: $(STAMP) opencl $(BUILT)

# Build the kernels of the usual calls ahead (`clsas info --check`: PoCL's disk cache keeps them),
# once per install and again when a kernel source changes; a failure only says so (setup goes on).
$(BUILT): $(STAMP) $(wildcard kernels/*.cl kernels/*.h) | opencl
	$(PY) -m clsas info --check > /dev/null && touch $@ || echo "clsas: kernels not built ahead (clsas info --check failed)"

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

# Without root: PoCL from pip (the clsas[pocl] extra), kept only when it builds and runs a kernel
# on this CPU (pip's PoCL fails on some CPUs, e.g. "unknown target CPU 'generic'" on AVX-512
# machines); otherwise it is removed again and the distribution's package is the way
# (`make setup` as root). `clsas info` says which driver the device comes from.
setup-pip-opencl: $(STAMP)
	$(PY) -m pip install --quiet -e '.[test,plot,pocl]'
	@if $(PY) -m clsas info --check > $(VENV)/clsas-info.json 2>&1; then \
	    echo "OpenCL works: $$(grep -h opencl_source $(VENV)/clsas-info.json)"; \
	else \
	    cat $(VENV)/clsas-info.json; \
	    $(PY) -m pip uninstall --quiet -y pocl-binary-distribution; \
	    echo "pip's PoCL gives no working device on this CPU and was removed; install the distribution's:"; \
	    echo "sudo apt-get install pocl-opencl-icd (or run make setup as root)"; \
	    exit 1; \
	fi

demo: setup
	$(PY) -m clsas demo

# The test modules run on the cores in parallel (pytest-xdist, a module a worker so that its
# fixtures are built once; at most 4 workers: each opens its own OpenCL context).
XDIST := -n auto --maxprocesses 4 --dist loadfile

test: setup
	CLSAS_REQUIRE_OPENCL=1 $(PY) -m pytest $(XDIST) -m "not slow" tests

test-all: setup
	CLSAS_REQUIRE_OPENCL=1 $(PY) -m pytest $(XDIST) tests

bench: setup
	$(PY) bench/run_all.py

clean:
	rm -rf $(VENV) build dist .pytest_cache
