# Two commands on a fresh machine:  make run  (the default workflow)  and  make test.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
CORES  ?= 2
ARGS   ?=

.PHONY: run test test-slow bench report clean-results

$(BIN)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[test]"
	touch $@

# snakemake --cores 2, after clearing what a killed run left (its lock, its unfinished jobs):
# see breastcore/workflow_run.py. More Snakemake arguments: make run ARGS="--configfile my.yaml".
run: $(BIN)/.installed          ## run the default scenes of config.yaml
	$(BIN)/python -m breastcore.workflow_run --cores $(CORES) $(ARGS)

test: $(BIN)/.installed         ## the unit suite (< 10 min on 2 cores)
	$(BIN)/pytest -n $(CORES) -q

test-slow: $(BIN)/.installed    ## long studies kept out of the unit suite
	$(BIN)/pytest -q -m slow

bench: $(BIN)/.installed        ## benchmark tables (medians over repeats)
	for b in benchmarks/bench_*.py; do $(BIN)/python $$b || exit 1; done

report: $(BIN)/.installed
	$(BIN)/snakemake --cores $(CORES) --report results/report.html

clean-results:
	rm -rf results/*/ .snakemake
