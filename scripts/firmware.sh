#!/usr/bin/env bash
# make firmware: host shared + static library of the C kernel, the golden-vector check on the
# host (plain and ASan+UBSan), and where arm-none-eabi-gcc and qemu-system-arm exist the
# Cortex-M4F image under QEMU (PASS/FAIL) with its flash and RAM.
# Model: $FIRMWARE_MODEL (a model directory), default the committed fixture.
set -euo pipefail
cd "$(dirname "$0")/.."
MODEL="${FIRMWARE_MODEL:-tests/fixtures/small_model}"
OUT="${FIRMWARE_OUT:-build/firmware}"
exec .venv/bin/python -m fogsf.bindings.firmware "$MODEL" --out "$OUT"
