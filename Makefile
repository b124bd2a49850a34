# Two commands on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test bench clean browser

$(STAMP): pyproject.toml constraints-cpu.txt
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -c constraints-cpu.txt -e '.[all,test]'
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/splatplan demo --out demo_out

# Headless Chromium for the viewer's browser test (Debian packages); skipped quietly when not root or
# apt is unavailable: the test then skips with its reason.
browser:
	@if ! command -v chromium >/dev/null 2>&1 && [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	  echo "installing chromium + chromium-driver for the browser test (apt)"; \
	  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver) >/dev/null 2>&1 \
	    || echo "note: could not install chromium; the browser test will skip"; \
	fi

test: $(STAMP) browser
	$(PY) -m pytest -q

# Every benchmark and study at full size (about 2 hours on 2 cores: the reach study alone takes about an hour), then the README tables.
bench: $(STAMP)
	$(PY) benchmarks/metric_throughput.py
	$(PY) benchmarks/metric_shell.py
	$(PY) benchmarks/robots_fk.py
	$(PY) benchmarks/render.py
	$(PY) benchmarks/encoders.py
	$(PY) benchmarks/scene_load.py
	$(PY) benchmarks/planners.py
	$(PY) benchmarks/viewer.py
	$(PY) benchmarks/engine.py
	$(VENV)/bin/splatplan eval throughput --out benchmarks/results
	$(VENV)/bin/splatplan eval pr --out benchmarks/results
	$(VENV)/bin/splatplan eval conservatism --out benchmarks/results
	$(VENV)/bin/splatplan eval linearization --out benchmarks/results
	$(VENV)/bin/splatplan eval arm --out benchmarks/results
	$(VENV)/bin/splatplan eval base --out benchmarks/results
	$(VENV)/bin/splatplan eval reach --out benchmarks/results
	$(VENV)/bin/splatplan eval navigate --out benchmarks/results
	$(PY) benchmarks/mbm_cpu.py benchmarks/results/mbm/default_spacing
	$(PY) benchmarks/update_readme.py

clean:
	rm -rf $(VENV) build demo_out
