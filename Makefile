# Two commands do all the set-up on a fresh machine: `make demo` and `make test`.
# Each creates .venv and installs mslab (with its test extras) into it when missing.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo test test-main test-emulated test-minimal lint lessons lab site bench clean venv docs

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	$(PY) -m ipykernel install --sys-prefix --name python3 >/dev/null
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(PY) -m mslab.demo --out out

# the generated pages: the effect table of docs/scenes.md, from the registered effects' schemas
# (a new effect file needs no hand edit there; test and site regenerate it first)
docs: $(STAMP)
	$(PY) -m mslab.effects.docs docs/scenes.md

# tests/ and the lessons under nbval (strict: every stored output) in one session of three workers,
# a whole file per worker at a time, the longest files first (tests/conftest.py: LONGEST_FIRST),
# so that no worker idles at the end of one part while another finishes it. nbval's cells
# run in order: -p no:randomly (pytest-randomly, where installed, would shuffle them).
# The main session runs three workers on the two cores: the hostile class (the longest file) waits
# on its sleepers' wall-clock backstops a third of its time, which a third worker fills (measured
# warm, same hour: 506 s against 556 s with two); the emulated part, compiling and CPU-bound, stays
# on two (152 s with three against 124 s).
PYTEST_2 := -m pytest -q -n 2 --dist loadfile --no-loadscope-reorder -p no:randomly
PYTEST_3 := -m pytest -q -n 3 --dist loadfile --no-loadscope-reorder -p no:randomly
NBVAL := --nbval --nbval-current-env --nbval-sanitize-with lessons/sanitize.cfg
# The three parts run side by side (each part's output is printed when it ends): run one after
# another, each part's tail left a core idle (the main part 11.6 min, then 2.8 and 0.9 min).
# They share nothing they write (the emulated part has its own compiled-code cache, the minimal
# part its own venv) and every test holds under load.
test: $(STAMP) docs
	$(VENV)/bin/ruff check .
	$(MAKE) --no-print-directory -j3 --output-sync=target test-main test-emulated test-minimal

test-main: $(STAMP)
	$(PY) $(PYTEST_3) $(NBVAL) tests lessons/
	$(PY) tools/lessons_check.py

# An emulated other CPU (README, "Testing on any machine"): numpy's runtime dispatch without
# AVX-512, numba compiling for a generic x86-64, OpenBLAS kernels of an older core, a fresh
# compiled-code cache. The lessons' stored outputs and the round-off-sensitive tests must
# pass here too: a result that changes with the CPU is a bug of the test or of the lesson.
EMULATED_CACHE := $(shell mktemp -d -u /tmp/mslab-emulated-XXXXXX)
EMULATED_CPU := NUMBA_CPU_NAME=generic MSLAB_CACHE_DIR=$(EMULATED_CACHE) NUMBA_CACHE_DIR=$(EMULATED_CACHE)
ifeq ($(shell uname -m),x86_64)
EMULATED_CPU += NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR" \
	OPENBLAS_CORETYPE=$(shell grep -qw avx2 /proc/cpuinfo && echo Haswell || echo Nehalem)
endif
EMULATED_TESTS := tests/test_implicit_cloth.py tests/test_newton_matrix.py tests/test_job_backend.py \
	tests/hard_cases/test_ledger_order.py tests/test_stability.py tests/test_spring_runs.py \
	tests/test_tree_solve.py tests/test_local_global_loop.py

test-emulated: $(STAMP)
	$(EMULATED_CPU) $(PY) $(PYTEST_2) -p no:cacheprovider $(NBVAL) $(EMULATED_TESTS) lessons/
	rm -rf $(EMULATED_CACHE)

# mslab where numba and cvxopt are not installed (a locked-down lab image): a second venv with
# pyproject's dependencies but those two, running tests that need neither (backend "auto" falls
# back to the numpy loops and scipy's sparse solvers; "numba" says what is missing). Two workers
# (pytest-xdist in that venv too), as the other parts: 103 s on one, 66 s on two (load ~8, same CPU).
MINIMAL := .venv-minimal
MINIMAL_DEPS := $(shell $(PYTHON) -c "import tomllib; print(' '.join(repr(d) for d in \
	tomllib.load(open('pyproject.toml', 'rb'))['project']['dependencies'] \
	if d.split('>')[0].split('=')[0] not in ('numba', 'cvxopt')))")
MINIMAL_TESTS := tests/test_no_numba.py tests/test_stability_exact.py tests/test_simulate.py \
	tests/test_scenes.py tests/test_integrators.py
$(MINIMAL)/.installed: pyproject.toml Makefile
	test -x $(MINIMAL)/bin/python || $(PYTHON) -m venv $(MINIMAL)
	$(MINIMAL)/bin/python -m pip install --quiet --upgrade pip
	$(MINIMAL)/bin/python -m pip install --quiet $(MINIMAL_DEPS) pytest hypothesis pytest-xdist
	$(MINIMAL)/bin/python -m pip install --quiet --no-deps -e .
	! $(MINIMAL)/bin/python -c "import numba" 2>/dev/null && ! $(MINIMAL)/bin/python -c "import cvxopt" 2>/dev/null
	touch $@

test-minimal: $(MINIMAL)/.installed
	$(MINIMAL)/bin/python $(PYTEST_2) -p no:cacheprovider $(MINIMAL_TESTS)

# markdown sentences with a number or verdict that no claim of the notebook backs (tools/lessons_check.py)
.PHONY: lessons-check
lessons-check: $(STAMP)
	$(PY) tools/lessons_check.py

# the lessons in JupyterLab, the student's way: JupyterLab's root is lessons/ (LAB_ROOT), so the
# repository's exercises/ (reference solutions, hidden tests) is outside it; the lessons' "Try it
# yourself" links point into lessons/student/, the student release of exercises/ (`mslab release`:
# solutions stripped, no hidden test), made when missing and never overwritten (a student's work
# lives there; delete the folder for a fresh copy). As root (uid 0, e.g. a container) --allow-root
# is passed, else Jupyter refuses to start. The venv is active in its terminals (`pytest`, `mslab`
# there are the venv's): bash reads the user's ~/.bashrc, which may put another Python first on
# PATH (pyenv, conda), and then the venv's activate script. tests/test_lab.py starts it so
# (LAB_ROOT: a copy of the lessons; LAB_ARGS: its port and token); tests/test_student_path.py
# checks the release the links reach.
LAB_ROOT ?= $(CURDIR)/lessons
LAB_STUDENT = $(LAB_ROOT)/student
LAB_RC ?= $(VENV)/lab.bashrc
LAB_ARGS ?=
# as root (a container, a lab image) JupyterLab refuses to start without --allow-root: given then
LAB_ROOT_FLAG := $(if $(filter 0,$(shell id -u)),--allow-root)
lab: $(STAMP)
	test -d "$(LAB_STUDENT)" || $(VENV)/bin/mslab release "$(CURDIR)/exercises" "$(LAB_STUDENT)"
	printf '[ -f ~/.bashrc ] && . ~/.bashrc\n. "%s/bin/activate"\n' "$(abspath $(VENV))" > $(LAB_RC)
	PATH="$(abspath $(VENV))/bin:$$PATH" VIRTUAL_ENV="$(abspath $(VENV))" $(VENV)/bin/jupyter lab \
	    --ServerApp.root_dir="$(LAB_ROOT)" --LabApp.default_url=/lab/tree \
	    --ServerApp.terminado_settings=shell_command="bash --rcfile $(abspath $(LAB_RC))" \
	    $(LAB_ROOT_FLAG) $(LAB_ARGS)

# re-execute every lesson in place (stored outputs then match the library; nbval checks them)
lessons: $(STAMP)
	$(PY) lessons/run_all.py

# the course as an offline static website in site/ (local MathJax; tools/build_site.py)
site: $(STAMP) docs
	$(PY) tools/build_site.py --out site

lint: $(STAMP)
	$(VENV)/bin/ruff check .

bench: $(STAMP)
	$(PY) -m mslab.cli bench

clean:
	rm -rf $(VENV) $(MINIMAL) out site .pytest_cache
