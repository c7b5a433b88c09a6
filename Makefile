# Two commands do all the set-up on a fresh machine: `make demo` and `make test`.
# Each creates .venv and installs mslab (with its test extras) into it when missing.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo test lint lessons site bench clean venv

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
	$(PY) tools/lessons_check.py

# markdown sentences with a number or verdict that no claim of the notebook backs (tools/lessons_check.py)
.PHONY: lessons-check
lessons-check: $(STAMP)
	$(PY) tools/lessons_check.py

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
