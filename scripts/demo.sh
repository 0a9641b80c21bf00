#!/usr/bin/env bash
# make demo: the main job on simulated data, from chamber logs to the firmware kernel.
#   1. simulate chamber runs at 0.5, 1 and 2 C/min (-40 -> 50 C, 10 deg/s)
#   2. inspect the test run (its SF error before compensation)
#   3. train the default model (lag-lstm, its structure chosen by the logs) on 0.5 and
#      2 C/min, test on 1 C/min (two training rates: one rate leaves the lags undetermined, see
#      docs/population.md; `make paper` runs the paper's one-rate protocol)
#   4. export it to ONNX and the generated C header
#   5. build the C kernel and replay the 1 C/min log through it, sample by sample
set -euo pipefail
cd "$(dirname "$0")/.."
OUT="${1:-out/demo}"
FOGSF=.venv/bin/fogsf
mkdir -p "$OUT"
step() { printf '\n== %s\n' "$*"; }

step "1/5 simulate chamber runs at 0.5, 1 and 2 C/min"
$FOGSF simulate --scenario paper --ramp-rate 0.5 --seed 1 --out "$OUT/run05.csv"
$FOGSF simulate --scenario paper --ramp-rate 1.0 --seed 2 --out "$OUT/run10.csv"
$FOGSF simulate --scenario paper --ramp-rate 2.0 --seed 3 --out "$OUT/run20.csv"

step "2/5 inspect the 1 C/min run"
$FOGSF inspect "$OUT/run10.csv"

step "3/5 train the default model on 0.5 and 2 C/min, test on 1 C/min"
$FOGSF train --train "$OUT/run05.csv" --train "$OUT/run20.csv" --test "$OUT/run10.csv" \
    --seed 0 --out "$OUT/model"

step "4/5 export to ONNX and C"
$FOGSF export "$OUT/model" --out "$OUT/build"

step "5/5 the C kernel, sample by sample, over the 1 C/min run"
$FOGSF replay "$OUT/model" "$OUT/run10.csv" --out "$OUT/corrected.csv" \
    --plot "$OUT/replay.png"

printf '\ndemo done: %s (logs, model/metrics.json, build/, corrected.csv, replay.png)\n' "$OUT"
