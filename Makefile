# fogsf: every target creates .venv itself on first use.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
FOGSF  := $(VENV)/bin/fogsf
STAMP  := $(VENV)/.installed
OUT    ?= out
# pytest workers, one a core (pytest-xdist); a test file stays on one worker (its fixtures
# are built once); PYTEST_WORKERS= runs the suite in one process
PYTEST_WORKERS ?= -n auto --dist loadfile

.PHONY: help venv test test-fast lint demo firmware firmware-cores misra export toolchain bench fuzz block-cores fuzz-block bench-diagnose bench-transfer bench-population bench-outside bench-hysteresis bench-plan bench-rate bench-scale bench-gsa bench-sim bench-rigs bench-bias bench-plateaus bench-fleet paper clean

help:
	@echo "make demo      simulate the paper's chamber runs, train, export, build, replay, report"
	@echo "make test      create .venv, ruff, mypy and the whole test suite"
	@echo "make test-fast ruff, mypy and the tests not marked slow: the check to run on every change"
	@echo "make firmware  build the C kernel (host library; Cortex-M4F image + size if arm-none-eabi-gcc exists)"
	@echo "make firmware-cores  golden vectors under QEMU on Cortex-M4F, M3 and M0: PASS/FAIL per core, flash, RAM, stack bound"
	@echo "make export    export the demo model to ONNX and C headers"
	@echo "make toolchain apt-install gcc-arm-none-eabi, libnewlib-arm-none-eabi, qemu-system-arm, clang, cmake, cppcheck (root only)"
	@echo "make bench     speed / size benchmarks (one and three models per image) -> out/bench.json"
	@echo "make misra     cppcheck's MISRA C:2012 addon on the kernel and generated models; fails on Mandatory/Required"
	@echo "make fuzz      libFuzzer + ASan + UBSan over the kernel until FUZZ_STEPS (1e7) steps"
	@echo "make block-cores  the calibration block's model: golden vectors under QEMU on M4F, M3, M0"
	@echo "make fuzz-block   libFuzzer + ASan + UBSan over the block loader until FUZZ_INPUTS (1e7) blocks"
	@echo "make paper     the paper's protocol: Table 2 side by side -> out/paper/"
	@echo "make bench-transfer  one ramp rate vs two, over seeds -> out/bench-transfer.json"
	@echo "make bench-diagnose  diagnose success rate over planted effects -> out/bench-diagnose.json"
	@echo "make bench-population  compensation on evaluation gyros of the population -> out/bench-population.json"
	@echo "make bench-outside  the default and its rivals on evaluation gyros given forms the population never draws (sensor, vent) -> out/bench-population-{sensor,vent}.json"
	@echo "make bench-hysteresis  the default with and without its hysteresis term, partial cycles, evaluation gyros -> out/bench-hysteresis.json"
	@echo "make bench-plan  the planned chamber program vs the paper's on evaluation gyros -> out/bench-plan.json"
	@echo "make bench-rate  one model at 10/100/1000 Hz; a 24 h 100 Hz replay, time and memory -> out/bench-sample-rate.json"
	@echo "make bench-scale  replay, inspect, diagnose, plan (train up to 24 h) on 2.4 h, 24 h and 7-day logs at 100 Hz, CSV and Parquet: wall, peak memory -> out/bench-scale.json"
	@echo "make bench-gsa   GSA against Rashedi et al. (2009) Table 4 -> out/bench-gsa.json"
	@echo "make bench-sim   simulator speed and its calibration to the paper -> out/bench-sim.json"
	@echo "make bench-rigs  rig logs (ROS, staircase, reversals, skew IMU) trained and scored against the truth -> out/bench-rigs.json"
	@echo "make bench-bias  the bias model on evaluation gyros (reversals from a standard and a fast loop, stationary; with and without a Shupe term) vs a PX4-style cubic -> out/bench-bias.json"
	@echo "make bench-plateaus  the plateau model on evaluation gyros (open- and closed-loop), three splits, vs the best polynomial in rate and T -> out/bench-plateaus.json"
	@echo "make lint      ruff"

$(STAMP): pyproject.toml constraints.txt
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	@echo "installing fogsf and its pinned packages into $(VENV) (about a minute the first time)"
	@bash -o pipefail -c "$(PY) -m pip install -q -c constraints.txt -e '.[dev]' 2>&1 \
	    | { grep -v 'is ignored: it is neither a file nor a directory' || true; }"
	touch $(STAMP)

venv: $(STAMP)

lint: $(STAMP)
	$(VENV)/bin/ruff check fogsf tests benchmarks

test: $(STAMP)
	$(VENV)/bin/ruff check fogsf tests benchmarks
	$(VENV)/bin/mypy
	$(PY) -m pytest -q -rs $(PYTEST_WORKERS) tests benchmarks/tests

# the tests a change can afford on every edit (under 3 min on 2 cores): the slow-marked ones left out
test-fast: $(STAMP)
	$(VENV)/bin/ruff check fogsf tests benchmarks
	$(VENV)/bin/mypy
	$(PY) -m pytest -q -rs $(PYTEST_WORKERS) -m "not slow" tests benchmarks/tests

demo: $(STAMP)
	bash scripts/demo.sh $(OUT)/demo

toolchain:
	bash scripts/toolchain.sh

# --- firmware: the C kernel, its export, speed and size, fuzzing ---
firmware: $(STAMP)
	bash scripts/firmware.sh

firmware-cores: $(STAMP)
	bash scripts/firmware_cores.sh

misra: $(STAMP)
	bash scripts/misra.sh

export: $(STAMP)
	bash scripts/export.sh $(OUT)/demo

bench: $(STAMP)
	bash scripts/bench.sh $(OUT)

fuzz: $(STAMP)
	bash scripts/fuzz.sh build/fuzz

# the calibration block (docs/firmware.md, "Calibration block")
block-cores: $(STAMP)
	$(PY) -m fogsf.bindings.cores $${FIRMWARE_MODEL:-tests/fixtures/small_model} --target block --out build/block-cores

fuzz-block: $(STAMP)
	$(PY) -m fogsf.bindings.fuzz --target block --out build/fuzz-block --inputs $${FUZZ_INPUTS:-10000000}

# --- the paper's protocol, Table 2 side by side (default gyro), ~4 min ---
paper: $(STAMP)
	$(PY) -m benchmarks.paper --out $(OUT)/paper

# --- one ramp rate vs two on the default gyro (noise seeds 0-7), ~2.5 min ---
bench-transfer: $(STAMP)
	$(PY) -m benchmarks.rate_transfer --out $(OUT)/bench-transfer.json

# --- compensation over the gyro population: evaluation seeds, ~34 min on 2 cores ---
POP_N ?= 24
bench-population: $(STAMP)
	$(PY) -m benchmarks.population --seeds eval --n $(POP_N) --out $(OUT)/bench-population.json

# --- the same gyros given each form outside the population's (docs/population.md)
OUTSIDE_MODELS ?= default,bank,physics2,node,poly
bench-outside: $(STAMP)
	for f in sensor vent; do $(PY) -m benchmarks.population --seeds eval --n $(POP_N) \
	  --models $(OUTSIDE_MODELS) --protocols a,b,e,f --workers 2 --outside $$f \
	  --out $(OUT)/bench-population-$$f.json || exit 1; done

# --- SF hysteresis: trained on partial cycles, tested on others; HYST_N gyros per group
# (with hysteresis, the same without it, gyros without it), evaluation seeds, ~9 min ---
HYST_N ?= 12
bench-hysteresis: $(STAMP)
	$(PY) -m benchmarks.hysteresis --seeds eval --n $(HYST_N) --workers 2 --kernel --out $(OUT)/bench-hysteresis.json

# --- a production line: new units with their design's prior (docs/fleet.md);
# FLEET_DESIGNS evaluation designs, FLEET_NEW new units each ---
FLEET_DESIGNS ?= 2
FLEET_NEW ?= 3
bench-fleet: $(STAMP)
	$(PY) -m benchmarks.fleet --seeds eval --designs $(FLEET_DESIGNS) --new $(FLEET_NEW) \
	  --workers 2 --out $(OUT)/bench-fleet.json

bench-plan: $(STAMP)
	$(PY) -m benchmarks.plan --out $(OUT)/bench-plan.json

# evaluation gyros 20020-20039 of the population (the final figures' range), 400 cases,
# ~2-5 min on 2 cores
bench-diagnose: $(STAMP)
	$(PY) -m benchmarks.diagnose_rate --seeds-from eval --first-seed 20020 --seeds 20 --out $(OUT)/bench-diagnose.json

# any sample rate: one model at 10/100/1000 Hz, and a 24 h 100 Hz log through
# `fogsf replay` for time and memory, ~2 min
bench-rate: $(STAMP)
	$(PY) -m benchmarks.sample_rate --out $(OUT)/bench-sample-rate.json

# replay and inspect on 2.4 h and 24 h logs at 100 Hz, CSV and Parquet: wall and peak memory
bench-scale: $(STAMP)
	$(PY) -m benchmarks.log_scale --out $(OUT)/bench-scale.json

# GSA on Rashedi's F1-F7 (N = 50, n = 30, T = 1000, 30 runs), ~1 min
bench-gsa: $(STAMP)
	$(PY) -m benchmarks.gsa_rashedi --out $(OUT)/bench-gsa.json

# a 3 h paper run's simulate and write time; the paper scenario's metrics over seeds 0-9
bench-sim: $(STAMP)
	$(PY) -m benchmarks.sim_paper --out $(OUT)/bench-sim.json

# --- rig logs end to end on evaluation gyros 20000-: train through the column map, score
# against the generator's truth; RIGS_N gyros a case
RIGS_N ?= 2
bench-rigs: $(STAMP)
	$(PY) -m benchmarks.rigs --seeds eval --n $(RIGS_N) --out $(OUT)/bench-rigs.json

BIAS_GYROS ?= 20000:20032
bench-bias: $(STAMP)
	$(PY) -m benchmarks.bias_eval --gyros $(BIAS_GYROS) --out $(OUT)/bench-bias.json

PLATEAU_GYROS ?= 20000:20016
bench-plateaus: $(STAMP)
	$(PY) -m benchmarks.plateaus --gyros $(PLATEAU_GYROS) --out $(OUT)/bench-plateaus.json

clean:
	rm -rf build out models
