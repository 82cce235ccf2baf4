# The two commands a newcomer runs: `make demo` and `make test`.
# The tests come in tiers (tests/tiers.py): `make test-fast` runs `unit` (the inner loop),
# `make test` runs `unit` and `integration`, `make acceptance` runs `acceptance` (measurements
# against bounds); CI (.ci/run) runs `make test`, then `make acceptance`. Each runs in parallel
# with pytest-xdist (unit and integration a file per worker, so that a module's fixtures are
# built once; acceptance a test per worker, a module's tests together where they share a
# fixture: xdist_group), prints its 25 slowest tests and writes every test's time to
# build/test-results/TARGET.xml (JUnit).
# `make test-busy TESTS="..."` runs the tests named with two CPU burners beside them.
# All create .venv when missing and install the project into it; only python3 and make are assumed.

PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.arenabench-installed
DEMO_OUT ?= demo-out
PYTEST_ARGS ?=
# Workers of make test and make test-fast: one more than the cores (many of those tests wait
# on the processes they start, so a core would idle), and of make acceptance: one per core
# (its tests render and fit: CPU all the way).
TEST_WORKERS ?= $(shell echo $$(( $$(nproc) + 1 )))
ACCEPTANCE_WORKERS ?= auto
RESULTS := build/test-results
# The parallel run of one target ($(3): how xdist hands out the tests, $(4): its workers), 25
# slowest tests, JUnit durations; pytest's exit 5 (no tests collected) fails the target.
define run_tier
	@mkdir -p $(RESULTS)
	@$(PY) -m pytest $(1) -n $(4) --dist $(3) --durations=25 \
	  --junitxml=$(RESULTS)/$(2).xml -o junit_suite_name=$(2) $(PYTEST_ARGS); rc=$$?; \
	  if [ $$rc -eq 5 ]; then echo "make $(2): pytest collected no tests - failing" >&2; exit 1; fi; \
	  exit $$rc
endef
BURNERS ?= 2
TESTS ?= tests/eval/commands/test_interrupts.py tests/eval/grade tests/eval/runs

.PHONY: demo test test-fast acceptance test-busy golden docs-images lint venv system-deps clean

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
test test-fast acceptance test-busy: export PYTHONDONTWRITEBYTECODE :=

test: $(STAMP) system-deps
	$(call run_tier,--tier unit --tier integration,test,loadfile,$(TEST_WORKERS))

test-fast: $(STAMP) system-deps
	$(call run_tier,--tier unit,test-fast,loadfile,$(TEST_WORKERS))

acceptance: $(STAMP) system-deps
	$(call run_tier,--tier acceptance,acceptance,loadgroup,$(ACCEPTANCE_WORKERS))

# The tests named in TESTS (any tier), serially, with BURNERS processes spinning on the CPU
# beside them for the whole run: what a busy shared machine does to waits and stops.
test-busy: $(STAMP) system-deps
	@mkdir -p $(RESULTS)
	@$(PY) tools/with_burners.py --burners $(BURNERS) -- $(PY) -m pytest $(TESTS) \
	  --durations=25 --junitxml=$(RESULTS)/test-busy.xml $(PYTEST_ARGS)

# Rewrite tests/data/golden_gt.json after a deliberate change of the generator's output
# (bump GENERATOR_VERSION in generator/dataset/make.py first; see docs/architecture.md).
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
