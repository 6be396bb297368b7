# pfbench: two-command setup.  `make all` builds .venv and produces the quick artefacts;
# `make test` builds .venv and runs the test suite.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
# pfbench's compiled kernels live in the environment (.venv/var/cache/pfbench, see
# pfbench.backends.cache.cache_root), so `make all` and the activated environment share them.
export NUMBA_CACHE_DIR ?= $(CURDIR)/.cache/numba
export MPLBACKEND := Agg

.PHONY: all full venv test test-slow bench bench-doc report mcu-tools clean compare-quick

# `pfbench compile` first: every model's default `pfbench run` kernel, on all cores, so the first
# run after setup loads its kernel instead of compiling it (the recipes reuse what they share).
all: $(STAMP) .venv-particles/.installed-stamp
	$(BIN)/pfbench compile
	$(BIN)/pfbench reproduce --all
	$(BIN)/pfbench report
	$(MAKE) compare-quick

# A quick leaderboard of the papers' objects: pfbench's methods and the `particles` library
# (out of process, in .venv-particles) on the same datasets -> results/compare/leaderboard.md
compare-quick: $(STAMP)
	$(BIN)/pfbench compare --task ob1,ob2,ob3-v4,thermal --runs 3 --particles 500 --quiet \
		--out results/compare --contender pfbench:bootstrap --contender pfbench:sir \
		--contender pfbench:multipdf:filters=5 --contender particles:bootstrap > /dev/null

# Paper scale: every recipe with --full; resumes after an interruption (finished recipes whose
# verified result matches this code and these settings are skipped).
full: $(STAMP)
	$(BIN)/pfbench reproduce --all --full
	$(BIN)/pfbench report

venv: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

# The suite runs on every core (pytest-xdist), one test file per worker at a time: most of its time
# is compiling numba kernels, and the tests of one file share theirs.
test: $(STAMP)
	$(BIN)/python -m pytest -q -n auto --dist loadfile -m "not slow" tests

test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow tests

# Benchmarks: pytest-benchmark suite plus `pfbench bench --all` (engine vs the C reference, the
# floor and `particles`; cold/warm start per method; cost vs N_p; busy machine; sweep; whole short
# runs at large N_p): JSON + PNG under
# results/bench/, then docs/PERFORMANCE.md regenerated from those JSON files and the kept
# docs/performance_notes.md. The `particles` comparison runs in its own environment
# (.venv-particles) because `particles` pins an older NumPy; see scripts/bench_particles.py.
bench: $(STAMP) .venv-particles/.installed-stamp
	mkdir -p results/bench
	$(BIN)/python -m pytest -q benchmarks --benchmark-enable --benchmark-json=results/bench/pytest-benchmark.json
	$(BIN)/pfbench bench --all
	$(BIN)/pfbench bench --document

# docs/PERFORMANCE.md from the results already in results/bench/ (no benchmark runs)
bench-doc: $(STAMP)
	$(BIN)/pfbench bench --document

.venv-particles/.installed-stamp:
	$(PYTHON) -m venv .venv-particles
	.venv-particles/bin/python -m pip install --quiet particles
	touch $@

report: $(STAMP)
	$(BIN)/pfbench report

# Cortex-M4 cross toolchain and emulator (issue: emulate the filter); root works here.
mcu-tools:
	bash scripts/install_mcu_tools.sh

clean:
	rm -rf $(VENV) .cache build *.egg-info
