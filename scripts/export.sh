#!/usr/bin/env bash
# make export: export the demo model ($1/model) to ONNX and C headers in $1/build.
set -euo pipefail
cd "$(dirname "$0")/.."
DEMO="${1:-out/demo}"
if [ ! -f "$DEMO/model/stream.json" ]; then
    echo "export: no demo model at $DEMO/model (stream.json): run \`make demo\` first" >&2
    exit 1
fi
exec .venv/bin/fogsf export "$DEMO/model" --out "$DEMO/build"
