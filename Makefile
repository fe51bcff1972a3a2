# Two commands on a fresh machine:  make run  (the default workflow)  and  make test.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
CORES  ?= 2
ARGS   ?=

.PHONY: run test test-slurm test-slow bench bench-full report clean-results

$(BIN)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[test,bench]"
	touch $@

# numba's cache of the compiled element loops, so that no job compiles them (again after an edit)
$(BIN)/.warm: $(BIN)/.installed $(wildcard breastcore/fem/compiled*.py) breastcore/fem/material.py \
              breastcore/fem/kernels.py
	$(BIN)/python -m breastcore.fem.warm
	touch $@

# snakemake --cores 2, after clearing what a killed run left (its lock, its unfinished jobs):
# see breastcore/pipeline/run.py. More Snakemake arguments: make run ARGS="--configfile my.yaml".
run: $(BIN)/.warm               ## run the default scenes of config.yaml
	$(BIN)/python -m breastcore.pipeline.run --cores $(CORES) $(ARGS)

# Debian's Chromium: tests/pipeline/test_workflow.py renders the HTML report in it, as a person
# would see it. Installed with apt-get when missing (root, or a user allowed to run apt-get).
# Another Chromium: make test CHROMIUM=/path/to/chromium (no install then).
CHROMIUM ?= /usr/bin/chromium
export CHROMIUM
$(CHROMIUM):
	apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium

# --dist loadfile: one worker runs each test file, so that a module-scoped fixture (the tiny
# workflow of tests/pipeline/test_workflow.py) is built once, not once per worker.
test: $(BIN)/.warm $(CHROMIUM)  ## the unit suite (< 10 min on 2 cores)
	$(BIN)/pytest -n $(CORES) --dist loadfile -q

# A real single-node SLURM on this machine runs a scene through Snakemake's SLURM executor
# (tests/pipeline/test_slurm.py): installs Debian's slurm-wlm and munge and the plugin; root.
test-slurm: $(BIN)/.installed   ## the workflow through a real SLURM (a few minutes)
	command -v slurmctld >/dev/null || (apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq slurm-wlm munge)
	$(BIN)/python -m pip install --quiet -e ".[test,slurm]"
	$(BIN)/pytest -q -m slurm tests/pipeline/test_slurm.py

test-slow: $(BIN)/.installed    ## long studies kept out of the unit suite
	$(BIN)/pytest -q -m slow

# Every benchmarks/bench_*.py, each printing its tables and its own wall time. `bench` runs
# each in its --quick mode (smaller levels and samples, same tables; minutes in all, see
# docs/benchmarks.md); `bench-full` runs the studies with their defaults (hours: fine50k
# solves, the 2,592-case stability grid, ultra-thin identifications). Neither needs a
# workflow run: a benchmark builds the meshes and inputs it needs.
BENCH_RUN = for b in benchmarks/bench_*.py; do \
	  echo "== $$b $(BENCH_FLAGS)"; start=$$(date +%s); \
	  $(BIN)/python $$b $(BENCH_FLAGS) || exit 1; \
	  echo "== $$b: $$(( $$(date +%s) - start )) s"; echo; \
	done

bench: BENCH_FLAGS = --quick
bench: $(BIN)/.installed        ## quick benchmark tables (medians over repeats)
	@$(BENCH_RUN)

bench-full: BENCH_FLAGS =
bench-full: $(BIN)/.installed   ## the full benchmark studies (hours)
	@$(BENCH_RUN)

report: $(BIN)/.installed
	$(BIN)/snakemake --cores $(CORES) --report results/report.html

clean-results:
	rm -rf results/*/ .snakemake
