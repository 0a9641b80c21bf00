#!/usr/bin/env bash
# make fuzz: the libFuzzer harness firmware/c/fuzz/fuzz_step.c (clang,
# -fsanitize=fuzzer,address,undefined) run until FUZZ_STEPS fogsf_step calls (default 1e7).
#   FUZZ_STEPS=100000 bash scripts/fuzz.sh build/fuzz     # a short run
# Crashes land in OUT/crashes/ (copy them to firmware/c/fuzz/corpus/ as regression inputs).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT="${1:-build/fuzz}"
STEPS="${FUZZ_STEPS:-10000000}"
exec .venv/bin/python -m fogsf.bindings.fuzz --out "$OUT" --steps "$STEPS"
