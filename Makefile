# Two entry points for a fresh machine: `make demo` and `make test`.
# Both create .venv when it is missing and install the project (editable) with its test extra.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.mi-npr-installed

.PHONY: demo test lint format docs bench clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

# Scene 1 of the paper, every drawing in one render: out/scene1.exr (every layer), the beauty
# with depth lines (scene1.png), the lines alone (scene1_lines.png/.svg), the apparent contours
# (scene1_contours.png/.svg) and the classified ray-tree edges (scene1_raytree.png/.svg).
demo: $(STAMP)
	$(VENV)/bin/mi-npr render scenes_xml/scene1.xml -o out --lines --contours --raytree

lint: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .

format: $(STAMP)
	$(VENV)/bin/ruff format .
	$(VENV)/bin/ruff check --fix .

# The Sphinx site, warnings as errors (-E: read every page again, so a warning never hides in
# a page an earlier build already read). Offline: nothing is fetched.
docs: $(STAMP)
	$(VENV)/bin/sphinx-build -E -W --keep-going -q -b html docs docs/_build/html

test: lint docs
	$(VENV)/bin/python -m pytest

bench: $(STAMP)
	for b in benchmarks/bench_*.py; do $(PY) $$b || exit 1; done

clean:
	rm -rf $(VENV) out build docs/_build *.egg-info .pytest_cache .ruff_cache
