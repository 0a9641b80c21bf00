#!/usr/bin/env bash
# make misra: cppcheck's MISRA C:2012 addon on the C kernel and on generated models of every
# shape (plain, bias head, play, cross terms, rate part; with MISRA_GSA=1 also the GSA
# search's largest LSTM, 3x256: firmware/c/MISRA.md, "The GSA-sized model");
# fails on any Mandatory or Required finding, on an Advisory rule firmware/c/MISRA.md does
# not record, or on a plain int in the kernel.
# Findings as JSON: $OUT/misra.json.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT="${OUT:-out}"
exec .venv/bin/python -m fogsf.bindings.misra --out build/misra --json "$OUT/misra.json" \
    ${MISRA_GSA:+--gsa}
