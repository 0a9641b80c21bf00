"""One module per `fogsf` sub-command: each has `configure(parser)` and `run(args) -> int`.

Heavy imports (torch, onnx) live inside `run`, so `fogsf inspect` starts fast.
"""

from __future__ import annotations

import argparse


def add_metric_options(parser: argparse.ArgumentParser) -> None:
    """--window-s and --latitude-deg, as every command that measures SF error takes them."""
    parser.add_argument("--window-s", type=float, default=100.0,
                        help="SF window length in seconds for the metrics (default 100)")
    parser.add_argument("--latitude-deg", type=float, default=None,
                        help="latitude for the earth rate when a log has no earth_rate_dps")
