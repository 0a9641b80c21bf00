#!/usr/bin/env bash
# make firmware-cores: the golden vectors bit for bit on a Cortex-M4F (hard float, QEMU
# mps2-an386), a Cortex-M3 (mps2-an385) and a Cortex-M0 (microbit), both soft float; PASS or
# FAIL per core with its flash, RAM, the stack bound of a call-graph walk of the image and,
# with the strict flags, the worst and mean instructions per sample.
# Models: $FIRMWARE_MODEL (a model directory), default the committed fixtures: the small
# model, and the rate-part model (format 7: the per-sample rate polynomial on every core).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT="${FIRMWARE_OUT:-build/cores}"
if [ -n "${FIRMWARE_MODEL:-}" ]; then
    exec .venv/bin/python -m fogsf.bindings.cores "$FIRMWARE_MODEL" --out "$OUT"
fi
.venv/bin/python -m fogsf.bindings.cores tests/fixtures/small_model --out "$OUT"
.venv/bin/python -m fogsf.bindings.cores tests/fixtures/rate_model --out "$OUT/rate_model"
