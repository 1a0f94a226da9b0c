# Everything a fresh machine needs: `make demo` and `make test` create .venv when missing.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
# Quiet installs: setuptools warns at every editable install of a package in its own checkout.
PIP := PYTHONWARNINGS=ignore::UserWarning $(BIN)/python -m pip install --quiet

.PHONY: demo test docs lint bench clean chromium

# The viewer's tests look at it in a real browser: Debian's headless Chromium.
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

# The runtime only, for `make demo`; bytecode is written as modules are first imported.
$(BIN)/ehm: pyproject.toml
	test -d $(VENV) || $(PYTHON) -m venv $(VENV)
	$(PIP) --upgrade pip
	$(PIP) --no-compile -e .
	touch $(BIN)/ehm

# Every extra and the development tools, for `make test`, `make docs`, `make lint`, `make bench`.
$(VENV)/dev: $(BIN)/ehm
	$(PIP) -e '.[dev]'
	touch $(VENV)/dev

demo: $(BIN)/ehm
	$(BIN)/ehm demo

# The linter first: a change that breaks the house's style fails as a failing test does.
test: lint chromium
	$(BIN)/python -m pytest -q

chromium:
	command -v chromium >/dev/null || ($(SUDO) apt-get update -qq && \
		DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq chromium >/dev/null)

lint: $(VENV)/dev
	$(BIN)/ruff check ehm tests benchmarks docs
	$(BIN)/ruff format --check ehm tests benchmarks docs

bench: $(VENV)/dev
	$(BIN)/python benchmarks/octomap_scan.py
	$(BIN)/python benchmarks/virtual_room.py
	$(BIN)/python benchmarks/grids.py
	$(BIN)/python benchmarks/kernel_selection.py
	$(BIN)/python benchmarks/paper_evaluation.py
	$(BIN)/python benchmarks/online_mapping.py
	$(BIN)/python benchmarks/scan_times.py
	$(BIN)/python benchmarks/startup.py
	$(BIN)/python benchmarks/soak.py
	$(BIN)/python benchmarks/raycast.py
	$(BIN)/python benchmarks/distance.py
	$(BIN)/python benchmarks/point_queries.py
	$(BIN)/python benchmarks/planner_loop.py
	$(BIN)/python benchmarks/bag_stream.py
	$(BIN)/python benchmarks/viewer.py
	$(BIN)/python benchmarks/tiles.py
	$(BIN)/python benchmarks/peers.py --seeds 0 --fractions 0.8
	$(BIN)/python benchmarks/nav2_maps.py
	$(BIN)/python benchmarks/changing_scene.py --seeds 0,1,2

clean:
	rm -rf $(VENV) build site *.egg-info

# The documentation site, into site/ (every warning an error).
docs: $(VENV)/dev
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict
