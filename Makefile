# The two commands a newcomer runs: `make demo` and `make test`.
# Inner loop while developing: `make test-fast` (skips tests marked slow, runs the rest in
# parallel with pytest-xdist, one file per worker so a module's fixtures are built once; CI runs
# `make test`, everything, one process).
# Both create .venv when missing and install the project into it; only python3 and make are assumed.

PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.arenabench-installed
DEMO_OUT ?= demo-out
PYTEST_ARGS ?=

.PHONY: demo test test-fast golden docs-images lint venv system-deps clean

$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV) || { \
	  echo "could not create $(VENV): on Debian/Ubuntu install python3-venv (apt-get install -y python3-venv)" >&2; exit 1; }
	$(PY) -m pip install --quiet --upgrade pip
	@# setuptools warns on every editable install that a folder named like the package could
	@# shadow it (10 lines; none here): hide that one warning, by its text; errors still show
	PYTHONWARNINGS="ignore:Editable installation" $(PY) -m pip install --quiet -e '.[test]'
	@# pyrender pins PyOpenGL 3.1.0, which cannot render on Python 3.12+: install the release
	@# that can over it, where this Python needs it (arenabench.glplatform says which)
	@req=$$($(PY) -c 'from arenabench.glplatform import pyopengl_requirement as r; print(r())') \
	  && if [ -n "$$req" ]; then echo "installing $$req over pyrender's PyOpenGL pin (this Python cannot render with 3.1.0)"; \
	  $(PY) -m pip install --quiet --no-deps "$$req"; fi
	@touch $(STAMP)

venv: $(STAMP)

system-deps:
	@bash tools/ensure-system-deps.sh

# Tests run with bytecode caching on even where the environment turns it off
# (PYTHONDONTWRITEBYTECODE): pytest then rewrites every test module's asserts afresh in each
# worker (8 s of collection against 2 s), and every `python -m arenabench` a test starts
# compiles the project's modules again.
test test-fast: export PYTHONDONTWRITEBYTECODE :=

test: $(STAMP) system-deps
	@$(PY) -m pytest $(PYTEST_ARGS); rc=$$?; \
	  if [ $$rc -eq 5 ]; then echo "make test: pytest collected no tests - failing" >&2; exit 1; fi; \
	  exit $$rc

test-fast: $(STAMP) system-deps
	@$(PY) -m pytest -m "not slow" -n auto --dist loadfile --durations=10 $(PYTEST_ARGS); rc=$$?; \
	  if [ $$rc -eq 5 ]; then echo "make test-fast: pytest collected no tests - failing" >&2; exit 1; fi; \
	  exit $$rc

# Rewrite tests/data/golden_gt.json after a deliberate change of the generator's output
# (bump GENERATOR_VERSION in generator/make.py first; see docs/architecture.md).
golden: $(STAMP)
	$(PY) -m tests.golden --update

# Re-render the README's images (docs/images/) after a change of the generator's output.
docs-images: $(STAMP)
	$(PY) tools/docs_images.py

demo: $(STAMP) system-deps
	@$(PY) -m arenabench demo --out $(DEMO_OUT) --example tests/data/task1c_image.jpg

lint: $(STAMP)
	$(PY) -m ruff check .

clean:
	rm -rf $(VENV) $(DEMO_OUT) build *.egg-info src/*.egg-info
