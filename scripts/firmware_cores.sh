#!/usr/bin/env bash
# make firmware-cores: the golden vectors bit for bit on a Cortex-M4F (hard float, QEMU
# mps2-an386), a Cortex-M3 (mps2-an385) and a Cortex-M0 (microbit), both soft float; PASS or
# FAIL per core with its flash, RAM and the stack bound of a call-graph walk of the image.
# Model: $FIRMWARE_MODEL (a model directory), default the committed fixture.
set -euo pipefail
cd "$(dirname "$0")/.."
MODEL="${FIRMWARE_MODEL:-tests/fixtures/small_model}"
OUT="${FIRMWARE_OUT:-build/cores}"
exec .venv/bin/python -m fogsf.bindings.cores "$MODEL" --out "$OUT"
