# Two commands do all the set-up on a fresh machine: `make demo` and `make test`.
# A second run reuses the virtual environment and the build (stamp files), starting in seconds.

PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
SUDO   := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
# Debian packages the test suite needs: a virtual X server, a window manager and xdotool for the
# windowed GUI tests (real keys and clicks), and Mesa's EGL/GL for offscreen rendering.
DEB_PACKAGES := xvfb xdotool openbox libegl1 libgl1-mesa-dri
EXT_SOURCES  := $(wildcard csrc/*.cpp csrc/*.h csrc/*.cu) setup.py

.PHONY: all setup system-deps build demo test test-fast lint docs screenshots cad-scenes clean

all: setup

setup: system-deps $(VENV)/.deps-installed $(VENV)/.ext-built

# Installed only when missing.
system-deps:
	@missing=$$(for p in $(DEB_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || echo $$p; done); \
	if [ -n "$$missing" ]; then \
		echo "installing Debian packages: $$missing"; \
		$(SUDO) apt-get update -qq && $(SUDO) apt-get install -y -qq --no-install-recommends $$missing; \
	fi

$(VENV)/bin/python:
	$(PYTHON) -m venv $(VENV)

# torch==2.13.0 comes first in requirements.txt so nothing pulls a CUDA build.
$(VENV)/.deps-installed: requirements.txt pyproject.toml | $(VENV)/bin/python
	$(BIN)/pip install -q -r requirements.txt
	touch $@

# The editable install builds edgedog.renderer._C against the environment's torch.
$(VENV)/.ext-built: $(VENV)/.deps-installed $(EXT_SOURCES)
	$(BIN)/pip install -q --no-build-isolation --no-deps -e .
	touch $@

build: $(VENV)/.ext-built

# With a display, the studio opens on the built-in scene; without one, the same job runs headless.
demo: setup
	@if [ -n "$$DISPLAY" ] || [ -n "$$WAYLAND_DISPLAY" ]; then $(BIN)/edgedog studio; else $(BIN)/edgedog demo; fi

# One pytest worker per core (pytest-xdist), a test file per worker at a time so that a file's
# module fixtures are built once; each worker's torch runs one thread (tests/conftest.py).
test: setup
	$(BIN)/python -m pytest -q -n auto --dist loadfile

# The quick tier: no slow test, no OpenGL, no window (markers declared in pyproject.toml).
test-fast: setup
	$(BIN)/python -m pytest -q -n auto --dist loadfile -m "not slow and not gl and not xvfb"

# ruff over the Python, clang-format (style in .clang-format) over the C++; all pinned in requirements.txt.
# Then import-linter over the packages as installed: edgedog/ with renderer/ and app/ linked in
# as edgedog.renderer and edgedog.app (it reads files, not setuptools' package-dir).
IMPORT_TREE := build/import-tree
lint: $(VENV)/.deps-installed
	$(BIN)/python -m ruff check .
	$(BIN)/clang-format --dry-run --Werror csrc/*.cpp csrc/*.h csrc/*.cu
	rm -rf $(IMPORT_TREE) && mkdir -p $(IMPORT_TREE)
	cp -rs $(CURDIR)/edgedog $(IMPORT_TREE)/edgedog
	cp -rs $(CURDIR)/renderer $(IMPORT_TREE)/edgedog/renderer
	cp -rs $(CURDIR)/app $(IMPORT_TREE)/edgedog/app
	cd $(IMPORT_TREE) && PYTHONPATH=. $(CURDIR)/$(BIN)/lint-imports $(CURDIR)/pyproject.toml

# docs/CLI.md from the command-line parsers (tests/test_cli_reference.py fails when it is stale).
docs: $(VENV)/.ext-built
	$(BIN)/python -m edgedog.tools.cli_reference --out docs/CLI.md

# The studio pictures in docs/, each from a scripted session on a virtual display, at the window
# size its script's name ends with (studio_1024x700.json), else 1600x1000.
screenshots: setup
	for script in docs/screenshots/*.json; do \
		runs=$$(mktemp -d); \
		size=$$(basename $$script .json | grep -o '[0-9]*x[0-9]*$$' || echo 1600x1000); \
		xvfb-run -a -s "-screen 0 1600x1000x24" $(BIN)/edgedog studio --size $$size --runs $$runs \
			--script $$script || exit 1; \
		rm -rf $$runs; \
	done

# The CAD benchmark's scenes (docs/suites/cad-benchmark.yaml): the 42 designs of the procedural
# family, ABC-NEF style (50 views at 800 px, PiDiNet maps), about 2 minutes each on 2 cores; the
# ones already made are kept.
CAD_SCENES := bench/cad-benchmark/scenes
cad-scenes: setup
	for i in $$(seq -w 0 41); do \
		[ -d $(CAD_SCENES)/family-$$i ] || $(BIN)/edgedog make-scene --family $$i --out $(CAD_SCENES)/family-$$i || exit 1; \
	done

clean:
	rm -rf $(VENV) build *.egg-info renderer/_C*.so
