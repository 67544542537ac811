# The two commands of the README are the contract: `make demo` and `make test` set up a fresh
# machine (a project-local .venv) and run. Nothing installed by hand is assumed.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
# two stamps: the demo needs the simulator, the command line and the page (pip install -e '.[sim,ui]': no
# numba, dask, pyarrow, pyads, playwright, pytest); the tests need every extra and the test stack
# (.[all,test])
DEMO_STAMP := $(VENV)/.installed-demo
STAMP      := $(VENV)/.installed

.PHONY: demo test bench stress clean docs chromium node linuxcnc

$(VENV)/bin/python:
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --disable-pip-version-check --upgrade pip

$(DEMO_STAMP): pyproject.toml | $(VENV)/bin/python
	$(PY) -m pip install -q --disable-pip-version-check -e '.[sim,ui]'
	touch $(DEMO_STAMP)

$(STAMP): pyproject.toml | $(VENV)/bin/python
	$(PY) -m pip install -q --disable-pip-version-check -e '.[all,test]'
	touch $(STAMP) $(DEMO_STAMP)
	rm -f $(WARM_STAMP)

# the batch kernels (numba) are compiled once at install time, into numba's disk cache beside the sources,
# so that the first `distctrl sweep` / `tune` loads them instead of compiling for tens of seconds (issue 27);
# again when a source they are built from changes (distctrl.batch.jitcache.SOURCES). Without numba (the
# demo's install) it says so and does nothing.
WARM_STAMP   := $(VENV)/.kernels-warm
KERNEL_SRCS  := $(wildcard distctrl/base/*.py distctrl/batch/*.py distctrl/control/*.py) \
                distctrl/sim/physics.py distctrl/errors/__init__.py

$(WARM_STAMP): $(DEMO_STAMP) $(KERNEL_SRCS)
	$(PY) -m distctrl.batch.warm
	touch $(WARM_STAMP)

demo: $(DEMO_STAMP) $(WARM_STAMP)
	$(PY) -m distctrl demo

# the browser tests (the HTML report's rendering test, tests/ui's live page) drive Debian's Chromium
# (/usr/bin/chromium); they never skip, so make test stops here if it cannot be installed
chromium:
	@command -v chromium >/dev/null 2>&1 || (apt-get update -qq && apt-get install -y -qq chromium >/dev/null) \
		|| (echo "make: Debian's chromium is needed for the browser tests (tests/workbench/test_report.py, tests/ui) and could not be installed (apt-get install chromium)" >&2; exit 1)
	@command -v chromium >/dev/null 2>&1 \
		|| (echo "make: chromium is still not on PATH after apt-get install chromium" >&2; exit 1)

# ads-client (npm, pinned in tests/ads/node/package-lock.json) is the tests' second real ADS client
# (issue 14). Node.js and npm come from Debian's packages; if they cannot be installed, make test stops
# here with that message (the tests never skip for it).
NODE_DIR   := tests/ads/node
NODE_STAMP := $(NODE_DIR)/node_modules/.distctrl-installed

$(NODE_STAMP): $(NODE_DIR)/package.json $(NODE_DIR)/package-lock.json
	@(command -v node >/dev/null 2>&1 && command -v npm >/dev/null 2>&1) \
		|| (apt-get update -qq && apt-get install -y -qq nodejs npm >/dev/null) \
		|| (echo "make: Node.js and npm are needed for the ads-client tests and could not be installed (apt-get install nodejs npm)" >&2; exit 1)
	cd $(NODE_DIR) && npm ci --no-audit --no-fund --loglevel=error
	touch $@

node: $(NODE_STAMP)

# LinuxCNC (issue 29, docs/linuxcnc.md): tests/linuxcnc run Debian's plasmac in halrun and build the bench's
# HAL component with halcompile (linuxcnc-uspace, linuxcnc-uspace-dev); they never skip, so make test stops
# here if the packages cannot be installed
# (xvfb: tests/linuxcnc/test_config.py starts LinuxCNC with QtPlasmaC's GUI on a virtual display)
linuxcnc:
	@(command -v halrun >/dev/null 2>&1 && command -v halcompile >/dev/null 2>&1 && command -v Xvfb >/dev/null 2>&1) \
		|| (apt-get update -qq && apt-get install -y -qq linuxcnc-uspace linuxcnc-uspace-dev xvfb >/dev/null) \
		|| (echo "make: Debian's linuxcnc-uspace, linuxcnc-uspace-dev and xvfb are needed for tests/linuxcnc and could not be installed (apt-get install linuxcnc-uspace linuxcnc-uspace-dev xvfb)" >&2; exit 1)
	@command -v halrun >/dev/null 2>&1 && command -v halcompile >/dev/null 2>&1 && command -v Xvfb >/dev/null 2>&1 \
		|| (echo "make: halrun/halcompile/Xvfb are still not on PATH after apt-get install linuxcnc-uspace linuxcnc-uspace-dev xvfb" >&2; exit 1)

test: $(STAMP) $(WARM_STAMP) chromium $(NODE_STAMP) linuxcnc
	$(PY) -m pytest -q -p no:cacheprovider --durations=30

bench: $(STAMP) $(WARM_STAMP)
	$(PY) bench/bench_core.py
	$(PY) bench/bench_batch.py
	$(PY) bench/bench_sweep.py --dask-sets 1000000
	$(PY) bench/bench_run.py
	$(PY) bench/bench_ads.py
	$(PY) bench/bench_identify.py
	$(PY) bench/bench_process.py
	$(PY) bench/bench_ui.py
	$(PY) bench/bench_record.py
	$(PY) -m distctrl benchmark --quick

# reliability suites (issue 8) at full length; figures go to bench/reliability.json and bench/soak.json
# make stress (issue 30): the long suites, then the resumable campaigns; state in $(STRESS_DIR), so a
# second `make stress` continues where the first stopped (docs/reliability.md "Resuming").
# DISTCTRL_STRESS_BUDGET=S gives each campaign call at most S seconds (exit 3 = not complete yet, the
# next call goes on); STRESS_TARGET sets the inputs per text suite, ADS_FRAMES the hostile ADS frames.
STRESS_DIR    ?= out/stress
STRESS_TARGET ?= 1000000
ADS_FRAMES    ?= 1000000
PAGE_INPUTS   ?= 100000
SOAK_CYCLES   ?= 100000000
ATHERIS_S     ?= 1800
STRESS_STAMP  := $(VENV)/.installed-stress

$(STRESS_STAMP): $(STAMP)
	$(PY) -m pip install -q --disable-pip-version-check -e '.[test,stress]'
	touch $@

stress: $(STRESS_STAMP) chromium $(NODE_STAMP)
	DISTCTRL_STRESS=1 DISTCTRL_FIGURES=bench $(PY) -m pytest -q -s -p no:cacheprovider tests/reliability
	$(PY) bench/soak.py --cycles 10000000
	$(PY) bench/soak.py --state $(STRESS_DIR) --cycles $(SOAK_CYCLES) --window 1000000; test $$? -ne 1
	for s in params nc scenario; do \
		$(PY) bench/stress.py run $$s --target $(STRESS_TARGET) --state $(STRESS_DIR) --figures ''; \
		test $$? -ne 1 || exit 1; done
	for s in params nc scenario; do \
		$(PY) bench/stress_atheris.py run $$s --budget $(ATHERIS_S) --state $(STRESS_DIR) || exit 1; done
	$(PY) bench/stress_serve.py ads --target $(ADS_FRAMES) --state $(STRESS_DIR); test $$? -ne 1
	$(PY) bench/stress_serve.py page --target $(PAGE_INPUTS) --state $(STRESS_DIR); test $$? -ne 1
	$(PY) bench/stress_serve.py pages --state $(STRESS_DIR)
	$(PY) bench/stress.py status --state $(STRESS_DIR) --figures bench/reliability.json

docs: $(STAMP)
	$(PY) -m distctrl.params.docgen > docs/parameters.md
	$(PY) -m distctrl.params.docgen --channel > docs/parameters-channel.md
	$(PY) -m distctrl.objects.docgen > docs/objects.md
	$(PY) -m distctrl.objects.channel3d > docs/objects-3d.md
	$(PY) -m distctrl.errors.three_d > docs/errors-3d.md
	$(PY) tools/law_figures.py --write
	$(PY) tools/traceability.py --write
	$(PY) tools/layer_map.py --svg docs/architecture-layers.svg > /dev/null

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .hypothesis $(NODE_DIR)/node_modules
