#!/usr/bin/env bash
# make bench: size / speed / instruction count of the C kernel -> $1/bench.json
set -euo pipefail
cd "$(dirname "$0")/.."
OUT="${1:-out}"
EXTRA=()
if [ -f "$OUT/demo/model/stream.json" ]; then EXTRA+=(--model "demo=$OUT/demo/model"); fi
exec .venv/bin/python -m benchmarks.firmware_bench --out "$OUT" "${EXTRA[@]}"
