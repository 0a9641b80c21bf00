"""What the `fogsf` sub-commands share: argument types, common options, reading the logs."""

from __future__ import annotations

import argparse

from fogsf.errors import UserError
from fogsf.logs.measure.sf_reference import forget_notes
from fogsf.logs.read import stream_read
from fogsf.logs.read.columns import Spill
from fogsf.logs.read.dialect import DELIMITERS, Dialect
from fogsf.logs.read.sampling import burst_window_s
from fogsf.training.interval.transfer import short_ramps


def _number(text: str) -> float:
    """`text` as a float, or argparse's refusal."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None


def positive_float(text: str) -> float:
    """An argparse type: a finite number > 0 (an SF ratio, a time)."""
    v = _number(text)
    if not (v > 0 and v != float("inf")):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return v


def _whole(text: str, least: int, bound: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if v < least:
        raise argparse.ArgumentTypeError(f"expected {bound}, got {text!r}")
    return v


def positive_int(text: str) -> int:
    """An argparse type: a whole number >= 1."""
    return _whole(text, 1, "at least 1")


def non_negative_int(text: str) -> int:
    """An argparse type: a whole number >= 0 (a count that may be none)."""
    return _whole(text, 0, "0 or more")


def non_negative_float(text: str) -> float:
    """An argparse type: a finite number >= 0 (a margin in seconds)."""
    v = _number(text)
    if not (v >= 0 and v != float("inf")):
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}")
    return v


class DefaultWindow(float):
    """--window-s's default, told from a value the user gave: a log written in bursts
    shorter than it takes its windows from the bursts (`read_logs`)."""


def add_metric_options(parser: argparse.ArgumentParser, skip: bool = False) -> None:
    """--window-s, --settle-s and --latitude-deg (with `skip`, --skip-s too), as every
    command that measures SF error takes them (docs/logs.md, "What the figures mean")."""
    parser.add_argument("--window-s", type=positive_float, default=DefaultWindow(100.0),
                        help="SF window length in seconds for the metrics (default 100; a "
                             "log written in shorter bursts: a burst's length): a "
                             "table-rate plateau is cut into windows of this length; a "
                             "shorter plateau (from 5 s) is one window")
    parser.add_argument("--settle-s", type=non_negative_float, default=2.0,
                        help="seconds left out after each change of the commanded table rate "
                             "while the table slews to it (default 2)")
    if skip:
        parser.add_argument("--skip-s", type=non_negative_float, default=0.0,
                            help="leave the log's first S seconds out of the metrics (the "
                                 "model still runs over them): for a log that starts while "
                                 "the temperature moves")
    parser.add_argument("--latitude-deg", type=float, default=None,
                        help=LATITUDE_HELP)
    parser.add_argument("--ref-temp-c", type=float, default=20.0, metavar="C",
                        help="board temperature whose SF is the reference of the SF error "
                             "(default 20); a log that never comes within 5 C of it takes "
                             "the nearest temperature it holds (said on stderr)")
    add_axis_cosine(parser)


LATITUDE_HELP = ("latitude for the earth rate when a log has no earth_rate_dps; the earth rate "
                 "from it assumes a vertical sensitive axis: give --axis-cosine for any other")


def add_earth_options(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """--latitude-deg and --axis-cosine, for commands with their own --window-s."""
    parser.add_argument("--latitude-deg", type=float, default=None, help=LATITUDE_HELP)
    add_axis_cosine(parser)


def add_axis_cosine(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """--axis-cosine: the earth rate from --latitude-deg on an axis that is not vertical
    (`read_logs` gives each log its cosine)."""
    parser.add_argument("--axis-cosine", type=axis_cosines, default=None,
                        metavar="C|x=C,y=C,...",
                        help="cosine between the sensitive axis and the local vertical (up), "
                             "-1 .. 1 (default 1): the earth rate from --latitude-deg is "
                             "EARTH_RATE * sin(latitude) * C; per axis for --axis all, e.g. "
                             "x=0.577,y=0.577,z=0.577; an earth_rate_dps column (or the "
                             "axis' earth_rate_A_dps) takes precedence")


def _cosine(text: str, where: str) -> float:
    try:
        c = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number -1 .. 1{where}, got {text!r}"
                                         ) from None
    if not -1.0 <= c <= 1.0:
        raise argparse.ArgumentTypeError(f"a cosine lies in -1 .. 1{where}, got {text!r}")
    return c


def axis_cosines(text: str) -> float | dict[str, float]:
    """An argparse type: `C` (every axis) or `x=C,y=C,...` (per axis), each C in -1 .. 1."""
    if "=" not in text:
        return _cosine(text.strip(), "")
    out: dict[str, float] = {}
    for part in (p for p in text.split(",") if p.strip()):
        axis, eq, value = (x.strip() for x in part.partition("="))
        if not eq or not axis or axis in out:
            raise argparse.ArgumentTypeError(
                f"expected C or AXIS=C pairs like x=0.577,y=0.577, got {part!r}")
        out[axis] = _cosine(value, f" for axis {axis}")
    return out


def cosine_for(cosines: float | dict[str, float] | None, axis: str | None) -> float:
    """The axis' cosine to the vertical from --axis-cosine (1.0 when not given)."""
    if cosines is None:
        return 1.0
    if isinstance(cosines, float):
        return cosines
    if axis is None:
        raise UserError("--axis-cosine AXIS=C,...: per-axis cosines need --axis (or a "
                        "single value for the one axis)")
    if axis not in cosines:
        raise UserError(f"--axis-cosine gives no cosine for axis {axis} (it has "
                        f"{', '.join(cosines)})")
    return cosines[axis]


def add_log_options(parser: argparse.ArgumentParser) -> None:
    """--delimiter, --decimal-comma, --columns, --gyro-column and --axis, as every command
    that reads chamber logs takes them (docs/logs.md)."""
    g = parser.add_argument_group("log format (docs/logs.md)")
    g.add_argument("--delimiter", choices=(",", ";", "tab"), default=None, metavar=",|;|tab",
                   help="cell delimiter (default: the one of , ; tab the header uses; a "
                        "header with several is refused)")
    g.add_argument("--decimal-comma", action="store_true",
                   help="numbers are written 20,5 (cells then separated by ; or tab)")
    g.add_argument("--columns", metavar="OURS=THEIRS,...|MAP.json", default=None,
                   help="map the log's columns to the format's names, e.g. "
                        "time_s=t,temp_c=temperature,table_rate_dps=table,gyro_dps=omega; "
                        "each name takes a column, a number or an expression over the "
                        "log's columns (time_s=sec + nanosec * 1e-9, valid=rig_ok == 1); "
                        'or a JSON/TOML file {"time_s": "t", ...}; default: '
                        "fogsf-columns.json (or .toml) beside each log, when there is one")
    g.add_argument("--gyro-column", metavar="NAME", default=None,
                   help="the column read as gyro_dps (one axis of a multi-axis log, e.g. "
                        "gyro_x_dps)")
    g.add_argument("--axis", metavar="X", default=None,
                   help="shorthand for --gyro-column gyro_X_dps; `--axis all` on train, inspect, "
                        "replay and export: every axis of the log in one run (docs/train.md)")
    g.add_argument("--sample-rate-hz", type=positive_float, default=None, metavar="HZ",
                   help="the log's sample rate, 1 .. 4000 Hz (default: from the median step "
                        "of time_s, which must lie within 20 %% of 1/HZ); time stamps rounded "
                        "coarser than the rows (a 10 Hz logger printing whole seconds) are "
                        "then replaced by the first stamp + row / HZ")
    g.add_argument("--max-gap-s", type=positive_float, default=None, metavar="S",
                   help="a step of time_s longer than S seconds is a gap: the log is then "
                        "segments, the gap filled with rows that measure nothing (default: "
                        "1 s, or 10 samples under 10 Hz); shorter steps are jitter or "
                        "dropped samples, kept as logged")
    g.add_argument("--allow-clock-offset", action="store_true",
                   help="join a stream ([join.NAME]) whose clock lies whole hours off the "
                        "log's as it is (default: refused as a time zone read as UTC; "
                        "tz = \"Europe/Berlin\" in the join puts a local clock on UTC)")
    g.add_argument("--bad-cells", choices=("refuse", "skip"), default="refuse",
                   help="a cell that holds no number (ERR, NaN, empty): refuse the log "
                        "(default), or skip: its row measures nothing (the model runs over "
                        "it, the cell filled from its neighbours)")
    g.add_argument("--gap-states", choices=("carry", "restart"), default="carry",
                   help="how a model's states cross a gap: carry (default: the gyro stayed "
                        "on, the temperature interpolated over the gap) or restart (it was "
                        "off: the next segment's first temperature held, the power-on rule)")


def dialect_from_args(args: argparse.Namespace):  # noqa: ANN201 - logs.read.dialect.Dialect
    """The `Dialect` the options of `add_log_options` give."""
    gyro = getattr(args, "gyro_column", None)
    axis = getattr(args, "axis", None)
    if axis is not None and gyro is not None:
        raise UserError("give --axis or --gyro-column, not both")
    if axis == "all":
        raise UserError("--axis all runs train, inspect, replay and export once per axis; "
                        "here give one axis, e.g. --axis x")
    given = getattr(args, "columns", None)
    cols = Dialect.parse_columns(given) if given else ()
    map_file = given if given and "=" not in given \
        and given.lower().endswith((".json", ".toml")) else None
    joins = Dialect.mapping_joins(map_file) if map_file else ()
    stream = Dialect.mapping_stream(map_file) if map_file else None
    layout = Dialect.mapping_layout(map_file) if map_file else None  # layout = "plateaus"
    delim = getattr(args, "delimiter", None)
    return Dialect(DELIMITERS[delim] if delim else None, cols, gyro,
                   decimal_comma=getattr(args, "decimal_comma", False),
                   sample_rate_hz=getattr(args, "sample_rate_hz", None), axis=axis,
                   joins=joins, max_gap_s=getattr(args, "max_gap_s", None),
                   gap_states=getattr(args, "gap_states", None) or "carry", stream=stream,
                   layout=layout,
                   allow_clock_offset=getattr(args, "allow_clock_offset", False),
                   bad_cells=getattr(args, "bad_cells", None) or "refuse")


def rated(model, sample_dt_s: float, what: str):  # noqa: ANN001, ANN201 - StreamModel
    """`model.at_rate(sample_dt_s)`, said on stdout when it changes the model (`what`: the
    rate's origin, e.g. "the log's 100 Hz")."""
    out = model.at_rate(sample_dt_s)
    if out is not model:
        print(f"model {model.model_id} re-rated for {what}: D {model.decimation} -> "
              f"{out.decimation} samples per {model.step_s:g} s step (model {out.model_id})")
    return out


def read_logs(args: argparse.Namespace, paths: list[str], on_disk: bool = False,
              training: bool = False) -> list:
    """Read logs with the options of `add_log_options`; how a log was read when it is not
    in the plain format (BOM, sniffed delimiter, column mapping) is said on stderr. Each log
    is read a block at a time with a progress bar on a terminal (logs/read/stream_read.py); with
    `on_disk` its columns stay in a spill on disk (replay, inspect, train, diagnose, plan
    --from-logs; what the command itself makes may still grow with the log), else they are
    then held in memory. `training`: logs to train on, whose ramps too short to count as
    ramps are said."""
    import sys

    forget_notes()
    dialect = dialect_from_args(args)
    logs = []
    for p in paths:
        spill = Spill()
        log = stream_read.read_log_on_disk(p, dialect, spill,
                                           progress=progress_bar(f"reading {p}", "rows"))
        if not on_disk:
            log = stream_read.in_memory(log)
            spill.close()
        logs.append(log)
    given = getattr(args, "axis_cosine", None)
    cosine = cosine_for(given, dialect.axis)
    ref_temp = getattr(args, "ref_temp_c", None)
    _windows_from_bursts(args, logs)
    for lg in logs:
        lg.axis_cosine = cosine
        if ref_temp is not None:
            lg.ref_temp_c = ref_temp
        if given is not None and lg.earth_rate_dps is not None:
            lg.read_notes = (*lg.read_notes, "--axis-cosine not used: the log has its earth "
                             "rate (earth_rate_dps)")
        if lg.read_notes:
            print(f"fogsf: read {lg.path}: {'; '.join(lg.read_notes)}", file=sys.stderr)
        for w in lg.read_warnings:  # a line of its own, so that it is not lost in the notes
            print(f"fogsf: warning: {lg.path}: {w}", file=sys.stderr)
        for r in short_ramps(lg) if training else ():
            print(f"fogsf: note: {lg.path}: {r.text()}", file=sys.stderr)
    return logs


def _windows_from_bursts(args: argparse.Namespace, logs: list) -> None:
    """--window-s not given and every log written in bursts shorter than the default: the
    windows are the bursts (the shortest log's), said on stderr."""
    import sys

    given = getattr(args, "window_s", None)
    if not isinstance(given, DefaultWindow) or not logs:
        return
    bursts = [burst_window_s(lg.extra.get("logged"), lg.sample_dt_s, float(given))
              for lg in logs]
    if any(b is None for b in bursts):
        return
    args.window_s = min(b for b in bursts if b is not None)
    print(f"fogsf: the logs are written in bursts of {args.window_s:g} s: windows of "
          f"{args.window_s:g} s, one a burst (--window-s to choose)", file=sys.stderr)


def progress_bar(desc: str, unit: str):  # noqa: ANN201 - a callable (done, total) or None
    """A progress bar on stderr told (done, total) as work advances; None (no bar) when
    stderr is not a terminal."""
    import sys

    if not sys.stderr.isatty():
        return None
    from tqdm import tqdm

    bar = None

    def tell(done: int, total: int) -> None:
        nonlocal bar
        if bar is None:
            bar = tqdm(total=total, desc=desc, unit=unit, unit_scale=True, leave=False)
        bar.update(done - bar.n)
        if done >= total:
            bar.close()

    return tell
