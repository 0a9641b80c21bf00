"""The `fogsf` entry point: one sub-command per module in fogsf.cli. Only the chosen
command's module is imported (the top-level --help lists COMMANDS' one-line help), so each
command starts with what it needs and no more (`fogsf inspect` never loads torch)."""

from __future__ import annotations

import argparse
import importlib
import re
import signal
import sys
from collections.abc import Collection
from typing import NoReturn

from fogsf import __version__, scratch
from fogsf.errors import UserError
from fogsf.fleet import batch

# name -> (module, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "simulate": ("fogsf.cli.simulate",
                 "simulate a FOG on a rate table in a temperature chamber (writes a log)"),
    "inspect": ("fogsf.cli.inspect",
                "a chamber log's summary and SF-error metrics: run this first on a new log"),
    "train": ("fogsf.cli.train",
              "train a compensation model (default lag-lstm; poly, polyrate, mlp, lstm, "
              "gsa-lstm)"),
    "export": ("fogsf.cli.export", "export a trained model to ONNX and C headers"),
    "replay": ("fogsf.cli.replay",
               "run the compiled C kernel over a log, sample by sample"),
    "diagnose": ("fogsf.cli.diagnose",
                 "fit the simulator to measured logs, name what it misses, extend it"),
    "plan": ("fogsf.cli.plan",
             "the chamber program that buys the most accuracy per chamber hour"),
    "fleet": ("fogsf.cli.fleet",
              "units of one design in one database: add, list, remove, check, report"),
}


# A value that starts with a negative number but is not one (LO:HI such as -20:60, a list
# such as -20,40,5) is taken by argparse for an option: it is joined to its option
# (--range -20:60 -> --range=-20:60).
_UNSIGNED = r"\d*\.?\d+(?:[eE][-+]?\d+)?"
NEGATIVE_RANGE = re.compile(rf"^-{_UNSIGNED}(?:[:,][-+]?{_UNSIGNED})+$")


def join_negative_ranges(argv: list[str]) -> list[str]:
    """`--opt -20:60` -> `--opt=-20:60` (and -20,40,5), so argparse reads it as a value."""
    out: list[str] = []
    for arg in argv:
        prev = out[-1] if out else ""
        if (NEGATIVE_RANGE.match(arg) and prev.startswith("--") and "=" not in prev
                and prev != "--"):
            out[-1] = f"{prev}={arg}"
        else:
            out.append(arg)
    return out


EXAMPLE_HEAD = re.compile(r"^(examples?):", re.IGNORECASE | re.MULTILINE)


def split_doc(doc: str) -> tuple[str, str | None]:
    """A command's docstring as (description, epilog): the examples go last in --help."""
    starts = [m.start() for m in EXAMPLE_HEAD.finditer(doc)]
    if not starts:
        return doc.strip(), None
    return doc[:starts[-1]].strip(), doc[starts[-1]:].strip()


class OneLineParser(argparse.ArgumentParser):
    """argparse's refusals in one line, as every other refusal of fogsf (exit status 2)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def chosen_command(argv: list[str]) -> str | None:
    """The sub-command `argv` names: its first word that is not an option (the top level
    has no option that takes a value), if it is a command."""
    first = next((a for a in argv if not a.startswith("-")), None)
    return first if first in COMMANDS else None


def build_parser(configure: Collection[str] | None = None) -> argparse.ArgumentParser:
    """The parser with the commands in `configure` (None: every command) complete, their
    modules imported; the others listed by their one-line help only."""
    parser = OneLineParser(
        prog="fogsf",
        description="Fiber-optic gyro thermal scale-factor error: from chamber logs to "
                    "firmware. Run `fogsf COMMAND --help` for each command.",
        epilog="Example:\n  fogsf simulate --scenario paper --ramp-rate 1.0 --out run10.csv"
               " && fogsf inspect run10.csv",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"fogsf {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, (module, help_text) in COMMANDS.items():
        if configure is not None and name not in configure:
            sub.add_parser(name, help=help_text)  # listed in --help, its module not loaded
            continue
        mod = importlib.import_module(module)
        desc, epilog = split_doc(mod.__doc__ or help_text)
        p = sub.add_parser(name, help=help_text, description=desc, epilog=epilog,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        mod.configure(p)
        p.set_defaults(_run=mod.run)
    return parser


def _exit_on_signal(signum: int, _frame: object) -> None:
    raise SystemExit(128 + signum)  # unwinds: temporary folders go, children are stopped


def main(argv: list[str] | None = None) -> int:
    scratch.sweep()  # the temporary folders of fogsf processes that were killed
    if argv is None:  # the `fogsf` process itself: every temporary file in its own folder
        batch.watch_parent()  # a unit of add-many: it ends with its batch, from its start
        scratch.claim_tempdir()
        for sig in (signal.SIGTERM, signal.SIGHUP):
            signal.signal(sig, _exit_on_signal)
    argv = join_negative_ranges(sys.argv[1:] if argv is None else list(argv))
    command = chosen_command(argv)
    args = build_parser(() if command is None else (command,)).parse_args(argv)
    args._argv = argv  # as given: a failed record names its retry from it
    try:
        return int(args._run(args) or 0)
    except UserError as e:
        print(f"fogsf {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("fogsf: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
