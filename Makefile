# Two commands do all the set-up on a fresh machine: `make demo` and `make test`.
# Each creates .venv and installs mslab (with its test extras) into it when missing.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo test lint lessons lab site bench clean venv

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	$(PY) -m ipykernel install --sys-prefix --name python3 >/dev/null
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(PY) -m mslab.demo --out out

test: $(STAMP)
	$(VENV)/bin/ruff check .
	$(PY) -m pytest -q -n 2 --dist loadfile tests
	$(PY) -m pytest -q -p no:randomly --nbval --nbval-current-env --nbval-sanitize-with lessons/sanitize.cfg lessons/

# the lessons in JupyterLab (file browser on lessons/, the repository as its root folder), the venv
# active in its terminals (`pytest`, `mslab` there are the venv's): bash reads the user's ~/.bashrc,
# which may put another Python first on PATH (pyenv, conda), and then the venv's activate script.
# tests/test_lab.py starts it so (LAB_ROOT: a copy of the lessons; LAB_ARGS: its port and token).
LAB_ROOT ?= $(CURDIR)
LAB_RC ?= $(VENV)/lab.bashrc
LAB_ARGS ?=
lab: $(STAMP)
	printf '[ -f ~/.bashrc ] && . ~/.bashrc\n. "%s/bin/activate"\n' "$(abspath $(VENV))" > $(LAB_RC)
	PATH="$(abspath $(VENV))/bin:$$PATH" VIRTUAL_ENV="$(abspath $(VENV))" $(VENV)/bin/jupyter lab \
	    --ServerApp.root_dir="$(LAB_ROOT)" --LabApp.default_url=/lab/tree/lessons \
	    --ServerApp.terminado_settings=shell_command="bash --rcfile $(abspath $(LAB_RC))" $(LAB_ARGS)

# re-execute every lesson in place (stored outputs then match the library; nbval checks them)
lessons: $(STAMP)
	$(PY) lessons/run_all.py

# the course as an offline static website in site/ (local MathJax; tools/build_site.py)
site: $(STAMP)
	$(PY) tools/build_site.py --out site

lint: $(STAMP)
	$(VENV)/bin/ruff check .

bench: $(STAMP)
	$(PY) -m mslab.cli bench

clean:
	rm -rf $(VENV) out site .pytest_cache
