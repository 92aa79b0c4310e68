# Entry points of the README. Each target installs what it needs into .venv by itself.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: venv venv-install demo demo-multi test conformance-models bench docs proto clean toxiproxy chromium gige nvim

# Two makes started at once (two terminals on a fresh clone) must not install into one .venv together: the
# install runs under a lock, and a make that waited for it finds the stamp fresh and installs nothing.
$(STAMP): pyproject.toml requirements.lock
	@flock $(VENV).lock $(MAKE) --no-print-directory venv-install

venv-install:
	@if [ -f $(STAMP) ] && [ $(STAMP) -nt pyproject.toml ] && [ $(STAMP) -nt requirements.lock ]; then :; else \
	  set -e; \
	  echo "creating $(VENV) with the pinned dependencies (requirements.lock)" >&2; \
	  $(PY) -m venv $(VENV); \
	  $(BIN)/pip install --quiet --upgrade pip; \
	  $(BIN)/pip install --quiet -r requirements.lock; \
	  $(BIN)/pip install --quiet --no-deps -e .; \
	  touch $(STAMP); \
	fi

venv: $(STAMP)

demo: $(STAMP)
	$(BIN)/aioadept demo $(ARGS)

# Four simulated robots, each calibrating its own camera at the same time, over one Zenoh router (docs/focus.md).
demo-multi: $(STAMP)
	$(BIN)/aioadept demo --config examples/multi-cell.toml $(ARGS)

# The fault matrix drives toxiproxy (a Go program) when it can be built here; without Go its cases skip.
toxiproxy:
	@if command -v go >/dev/null 2>&1; then scripts/install_toxiproxy.sh || echo "toxiproxy build failed: its fault-matrix cases will skip" >&2; \
	else echo "no Go toolchain: the toxiproxy fault-matrix cases will skip" >&2; fi

# The live viewer's browser test drives Debian's headless Chromium; installed here when missing and this machine
# allows it (root with apt-get). Without it that test skips and says why.
chromium:
	@if [ -x /usr/bin/chromium ]; then :; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	  echo "installing chromium (Debian package) for the viewer's browser test" >&2; \
	  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null) || \
	  echo "chromium install failed: the viewer's browser test will skip" >&2; \
	else echo "no /usr/bin/chromium and no root apt-get: the viewer's browser test will skip" >&2; fi

# Neovim (Debian's neovim) for the V+ language server's editor test (tests/integration/test_vplus_neovim.py),
# installed when missing and this machine allows it (root with apt-get); without it that test skips and says why.
nvim:
	@if command -v nvim >/dev/null 2>&1; then :; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	  echo "installing neovim (Debian package) for the V+ language server's editor test" >&2; \
	  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq neovim >/dev/null) || \
	  echo "neovim install failed: the V+ editor test will skip" >&2; \
	else echo "no nvim and no root apt-get: the V+ editor test will skip" >&2; fi

# The GigE Vision source's extra (pyproject's [gige]: aravis-python, PyGObject) and the Debian packages PyGObject
# builds with, installed when missing and this machine allows it (root with apt-get). Without them the GigE tests
# (tests/integration/test_gige_camera.py, against Aravis's fake camera on 127.0.0.1) skip and say why.
GIGE_PINS := aravis-python==0.8.31.post1 pygobject==3.50.2 pycairo==1.29.2
GIGE_DEBS := libgirepository1.0-dev libcairo2-dev pkg-config libusb-1.0-0
gige: $(STAMP)
	@if $(BIN)/python -c "import aravis, gi" >/dev/null 2>&1; then :; else \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1 && \
	     ! dpkg -s $(GIGE_DEBS) >/dev/null 2>&1; then \
	    echo "installing $(GIGE_DEBS) (Debian packages) for the GigE source's PyGObject" >&2; \
	    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(GIGE_DEBS) >/dev/null) || \
	    echo "apt-get failed: PyGObject may not build" >&2; \
	  fi; \
	  $(BIN)/pip install --quiet $(GIGE_PINS) || echo "[gige] extra failed to install: the GigE tests will skip" >&2; \
	fi

# pytest exits 5 when it collected no tests: that is a failure, not a pass. Two test processes (pytest-xdist), each
# taking whole files (--dist loadfile: a file's module fixtures and servers stay in one process): about 14 min on
# 2 cores instead of about 25 in one. ARGS adds pytest options (ARGS="-p no:xdist" for one process).
test: $(STAMP) toxiproxy chromium gige nvim
	$(BIN)/python -m pytest -q -rsfE -n 2 --dist loadfile $(ARGS); rc=$$?; \
	if [ $$rc -eq 5 ]; then echo "no tests were collected" >&2; exit 1; fi; exit $$rc

# The whole conformance suite (tests/conformance) on every robot model (viper-s850, viper-s650, cobra-s600,
# cobra-s800), each on both backends: the Python sim and the V+ server on the emulator. `make test` runs it whole
# on the Viper s850 only and a model-differences subset on the others (docs/sim.md, "Robot models").
conformance-models: $(STAMP)
	AIOADEPT_CONFORMANCE_MODELS=all $(BIN)/python -m pytest tests/conformance -q -rsfE $(ARGS); rc=$$?; \
	if [ $$rc -eq 5 ]; then echo "no tests were collected" >&2; exit 1; fi; exit $$rc

# Every benchmarks/bench_*.py in turn, each JSON kept under runs/bench-*/, then one verdict table
# (ARGS=--quick for a smoke run, ARGS="--only bench_bus" for one).
bench: $(STAMP)
	$(BIN)/python benchmarks/run_all.py $(ARGS)

# The documentation site (mkdocs.yml) into site/: every warning is an error, links between pages are checked, and
# nothing is fetched from the internet. Open site/index.html, or serve it with `.venv/bin/mkdocs serve`.
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --quiet

# Regenerate the Protobuf code committed under src/aioadept/bus/.
proto: $(STAMP)
	$(BIN)/pip install --quiet grpcio-tools==1.85.1
	cd src/aioadept/bus && ../../../$(BIN)/python -m grpc_tools.protoc -I. --python_out=. --pyi_out=. epypes.proto aioadept.proto

clean:
	rm -rf $(VENV) build site *.egg-info src/*.egg-info .pytest_cache
