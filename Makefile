# The two commands: `make demo` and `make test`. Both install the system packages where the user is
# root (scripts/setup-system.sh: Chromium, OSMesa/EGL, Blender, Node.js; one line and nothing changed
# otherwise) and create .venv when it is missing.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
SYSTEM_STAMP := build/.system-packages

.PHONY: demo test bench clean system

# System packages, once per checkout (again when the script changes; `make system` forces it).
$(SYSTEM_STAMP): scripts/setup-system.sh
	sh scripts/setup-system.sh
	@mkdir -p $(@D) && touch $@

system:
	sh scripts/setup-system.sh

$(STAMP): pyproject.toml | $(SYSTEM_STAMP)
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[all,ray,dev]'
	touch $(STAMP)

# The HTML viewer's JavaScript (kinodyn.viz.html): the viewer code in viz-js/src bundled with three.js
# from npm by esbuild (versions pinned in viz-js/package-lock.json). Needs Node.js >= 18 and npm.
VIZ_BUNDLE := src/kinodyn/viz/assets/viewer.js
$(VIZ_BUNDLE): viz-js/package.json viz-js/package-lock.json viz-js/src/viewer.js | $(SYSTEM_STAMP)
	@command -v npm >/dev/null 2>&1 || { echo "make: npm not found: the HTML viewer bundle is built from viz-js/ with Node.js (>= 18) and npm (Debian: apt-get install nodejs npm)" >&2; exit 1; }
	cd viz-js && npm ci --no-audit --no-fund --loglevel=error || { echo "make: 'npm ci' in viz-js/ failed: the viewer bundle needs three.js and esbuild from the npm registry; is it reachable?" >&2; exit 1; }
	cd viz-js && npm run --silent build

demo: $(SYSTEM_STAMP) $(STAMP) $(VIZ_BUNDLE)
	$(BIN)/kinodyn demo --out out

test: $(SYSTEM_STAMP) $(STAMP) $(VIZ_BUNDLE)
	$(BIN)/python -m pytest -q -n 2 --dist loadfile

bench: $(STAMP) $(VIZ_BUNDLE)
	$(BIN)/kinodyn bench io --json out/bench-io.json
	$(BIN)/kinodyn bench viz --json out/bench-viz.json

clean:
	rm -rf out build .pytest_cache $(VIZ_BUNDLE)
