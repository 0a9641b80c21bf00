"""fogsf simulate: not built yet (see the open issues)."""

from __future__ import annotations

import argparse

from trainer.errors import UserError


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("args", nargs="*", help=argparse.SUPPRESS)


def run(args: argparse.Namespace) -> int:
    raise UserError("'fogsf simulate' is not built yet")
