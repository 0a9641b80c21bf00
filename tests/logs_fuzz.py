"""Corrupted logs through the CLI: small logs in every format the reader takes (CSV, Parquet,
and with the `rigs` extra ROS 1 and ROS 2 bags, MCAP, PX4 ULog, TDMS) corrupted at random
(cells, lines, bytes, units, time stamps, column maps) and read with `fogsf inspect`
in-process. Every run must end in exit 0 or 2 (a one-line refusal); an exception out of
`main` is a traceback. tests/test_logs_fuzz.py runs a few hundred; as a probe:

    .venv/bin/python tests/logs_fuzz.py --files 10000 --seed 1

prints the count of tracebacks and where they were raised.
"""

from __future__ import annotations

import contextlib
import io
import logging
import math
import shutil
import sys
import traceback
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from fogsf.cli.main import main  # noqa: E402
from fogsf.logs.read import columns as columns_mod  # noqa: E402

N_ROWS = 900  # 90 s at 10 Hz: +/-10 deg/s plateaus of 15 s over 16 .. 24 C
RATE_HZ = 10.0
EPOCH_NS = 1_772_612_100 * 10**9
NAMES = ("time_s", "temp_c", "table_rate_dps", "gyro_dps", "earth_rate_dps")
TOKENS = ("", "nan", "NaN", "inf", "-inf", "ERR", "1e400", "abc", "0", "-0", "1,5", '"',
          "1e-320", "9" * 30, " ", "--", "0x10", "\u0661", "1e6", "-1e6", "3600", "1.5.2",
          "true", "#", "\t")
MAPS = ('gyro_dps = "gyro_dps * 57.29577951308232"\n', 'valid = "temp_c > 100"\n',
        'time_s = "time_s * 0"\n', 'time_s = "((("\n', "table_rate_dps = 0\n",
        'table_rate_dps = "-table_rate_dps"\n', 'temp_c = "temp_c + 273.15"\n',
        'time_s = "round_me"\n', '[join.x]\nfile = "nothere.csv"\ntime_s = "t"\n',
        "= = =\n", 'gyro_dps = "gyro_dps / table_rate_dps"\n', 'valid = "gyro_dps"\n',
        'time_s = "unwrap(time_s, 0)"\n', 'earth_rate_dps = "1 / (temp_c - temp_c)"\n')


def signals(rng: np.random.Generator) -> dict[str, np.ndarray]:
    """A small log's columns: a gyro with a temperature-dependent SF on +/- plateaus."""
    t = np.arange(N_ROWS) / RATE_HZ
    temp = 16.0 + 8.0 * t / t[-1]
    table = np.where((np.arange(N_ROWS) // 150) % 2 == 0, 10.0, -10.0)
    earth = np.full(N_ROWS, 0.00234)
    gyro = table * (1.0 + 1e-4 * (temp - 20.0)) + earth + rng.normal(0, 1e-4, N_ROWS)
    return dict(zip(NAMES, (t, temp, table, gyro, earth), strict=True))


def _csv_text(cols: dict[str, np.ndarray]) -> str:
    rows = np.column_stack(list(cols.values()))
    return "\n".join([",".join(cols), *(",".join(f"{v:.10g}" for v in r) for r in rows)]) + "\n"


def _as_run(cols: dict[str, np.ndarray]) -> SimpleNamespace:
    """The fields of a rig run that tests/test_raw_formats.py's writers read."""
    return SimpleNamespace(axes={"": SimpleNamespace(gyro_dps=cols["gyro_dps"],
                                                      temp_c=cols["temp_c"])},
                           stamp_s=cols["time_s"], command_dps=cols["table_rate_dps"])


def make_bases(root: Path, seed: int = 0) -> dict[str, Path]:
    """The folder of each format's base log (its file and a map beside it where it needs
    one), by kind; kinds whose library is missing are left out."""
    rng = np.random.default_rng(seed)
    cols = signals(rng)
    out: dict[str, Path] = {}

    def folder(kind: str) -> Path:
        f = root / kind
        f.mkdir(parents=True, exist_ok=True)
        out[kind] = f
        return f

    (folder("csv") / "log.csv").write_text(_csv_text(cols))
    import pyarrow as pa
    import pyarrow.parquet as pq

    pq.write_table(pa.table(cols), folder("parquet") / "log.parquet")
    with contextlib.suppress(ImportError):
        import rosbags  # noqa: F401
        import test_raw_formats as raw

        for kind, name in (("ros1", "log.bag"), ("ros2", "log"), ("mcap", "log")):
            f = folder(kind)
            raw._write_ros(f / name, _as_run(cols), kind == "ros1", kind == "mcap")
            (f / "fogsf-columns.toml").write_text(raw.ROS_MAP)
    with contextlib.suppress(ImportError):
        import pyulog  # noqa: F401
        import test_raw_formats as raw

        _write_ulog(folder("ulog"), cols, raw)
    with contextlib.suppress(ImportError):
        import nptdms  # noqa: F401

        _write_tdms(folder("tdms"), cols)
    return out


def _write_ulog(f: Path, cols: dict[str, np.ndarray], raw) -> None:  # noqa: ANN001
    us = np.round(cols["time_s"] * 1e6).astype(np.int64) + 5_000_000
    change = np.flatnonzero(np.diff(cols["table_rate_dps"], prepend=np.nan) != 0)
    raw._ulog(f / "log.ulg", {
        "sensor_gyro": ([("uint64_t", "timestamp"), ("double", "z"), ("float", "temperature")],
                        np.column_stack([us, cols["gyro_dps"] / 57.29577951308232,
                                         cols["temp_c"]])),
        "table_command": ([("uint64_t", "timestamp"), ("double", "rate_dps")],
                          np.column_stack([us[change], cols["table_rate_dps"][change]]))})
    (f / "fogsf-columns.toml").write_text('''stream = "sensor_gyro"
time_s = "timestamp * 1e-6"
gyro_dps = "z * 57.29577951308232"
temp_c = "temperature"
earth_rate_dps = 0.00234

[join.table]
stream = "table_command"
time_s = "timestamp * 1e-6"
table_rate_dps = "rate_dps"
how = "hold"
''')


def _write_tdms(f: Path, cols: dict[str, np.ndarray]) -> None:
    """Half the time a waveform group (no time channel: wf_start_time, wf_increment)."""
    from nptdms import ChannelObject, TdmsWriter

    start = np.datetime64(EPOCH_NS, "ns")
    props = {"wf_start_time": start, "wf_increment": 1.0 / RATE_HZ}
    with TdmsWriter(str(f / "log.tdms")) as w:
        w.write_segment([ChannelObject("rig", n, cols[n], properties=props)
                         for n in ("temp_c", "table_rate_dps", "gyro_dps", "earth_rate_dps")])


# --- corruptions ------------------------------------------------------------------------------

def _lines_op(rng: np.random.Generator, lines: list[str]) -> list[str]:
    """One corruption of a CSV's lines."""
    n = len(lines)
    i = int(rng.integers(0, max(n, 1)))
    op = int(rng.integers(0, 14))
    if not lines:
        return ["time_s"]
    if op == 0:  # a cell
        cells = lines[i].split(",")
        cells[int(rng.integers(0, len(cells)))] = str(rng.choice(TOKENS))
        lines[i] = ",".join(cells)
    elif op == 1:
        del lines[i]
    elif op == 2:
        lines.insert(i, lines[i])
    elif op == 3:
        j = int(rng.integers(0, n))
        lines[i], lines[j] = lines[j], lines[i]
    elif op == 4:
        lines = lines[:i]
    elif op == 5:
        lines.insert(i, "".join(chr(int(c)) for c in rng.integers(1, 0x3000, 12)))
    elif op == 6:
        lines[i] = lines[i].replace(",", str(rng.choice([";", "\t", " ", ",,"])))
    elif op in (7, 8, 9, 10):  # a column: dropped, rounded, scaled, made constant
        k = int(rng.integers(0, len(lines[0].split(","))))
        lines = [_col_op(rng, op, k, ln, r) for r, ln in enumerate(lines)]
    elif op == 11:
        lines[0] = lines[0].replace(str(rng.choice(NAMES)), str(rng.choice(TOKENS + NAMES)))
    elif op == 12:  # a clock step (back or forward) from a row on
        step = float(rng.choice([-3600.0, -30.0, -0.1, 0.05, 7.0, 3600.0, 1e5]))
        lines = [_shift(ln, step) if r > i else ln for r, ln in enumerate(lines)]
    else:
        lines = lines[:1]
    return lines


def _col_op(rng: np.random.Generator, op: int, k: int, line: str, row: int) -> str:
    cells = line.split(",")
    if k >= len(cells):
        return line
    if op == 7:
        del cells[k]
    elif row > 0:
        try:
            v = float(cells[k])
        except ValueError:
            return line
        if op == 8:
            v = float(np.round(v))
        elif op == 9:
            v *= float(rng.choice([0.0, -1.0, 1000.0, 1 / 6, math.pi / 180]))
        else:
            v = 1.0
        cells[k] = f"{v:.10g}"
    return ",".join(cells)


def _shift(line: str, step: float) -> str:
    cells = line.split(",")
    try:
        cells[0] = f"{float(cells[0]) + step:.10g}"
    except ValueError:
        pass
    return ",".join(cells)


def _bytes_op(rng: np.random.Generator, data: bytes) -> bytes:
    """One corruption of a file's bytes."""
    b = bytearray(data)
    if not b:
        return bytes(rng.integers(0, 256, 16, dtype=np.uint8))
    op = int(rng.integers(0, 5))
    i = int(rng.integers(0, len(b)))
    if op == 0:
        for j in rng.integers(0, len(b), int(rng.integers(1, 10))):
            b[int(j)] = int(rng.integers(0, 256))
    elif op == 1:
        del b[i:]
    elif op == 2:
        del b[i:i + int(rng.integers(1, 256))]
    elif op == 3:
        b[i:i] = b[i:i + int(rng.integers(1, 256))]
    else:
        b[i:i + int(rng.integers(1, 64))] = bytes(64)[:int(rng.integers(1, 64))]
    return bytes(b)


def corrupt(kind: str, base: Path, dst: Path, rng: np.random.Generator) -> Path:
    """A corrupted copy of the base folder of `kind` in `dst`; the path to read."""
    shutil.copytree(base, dst)
    target = next(p for p in sorted(dst.iterdir()) if p.name != "fogsf-columns.toml")
    files = sorted(target.rglob("*")) if target.is_dir() else [target]
    files = [f for f in files if f.is_file()]
    victim = files[int(rng.integers(0, len(files)))]
    for _ in range(int(rng.integers(1, 4))):
        if kind == "csv" and rng.random() < 0.8:
            lines = victim.read_text(errors="replace").split("\n")
            victim.write_text("\n".join(_lines_op(rng, lines)))
        elif kind == "parquet" and rng.random() < 0.5:
            _parquet_op(rng, victim)
        else:
            victim.write_bytes(_bytes_op(rng, victim.read_bytes()))
    if rng.random() < 0.1:
        m = dst / "fogsf-columns.toml"
        m.write_text((m.read_text() if m.exists() else "") + str(rng.choice(MAPS)))
    return target


def _parquet_op(rng: np.random.Generator, path: Path) -> None:
    """A corruption of a Parquet log's values: a column of text, with nulls, integers,
    scaled, rounded, or dropped."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        t = pq.read_table(path)
    except Exception:  # noqa: BLE001 - already broken: leave it
        return
    name = t.column_names[int(rng.integers(0, t.num_columns))] if t.num_columns else None
    if name is None:
        return
    v = np.asarray(t[name].to_numpy(zero_copy_only=False))
    op = int(rng.integers(0, 6))
    if op == 0:
        col: pa.Array = pa.array([str(x) for x in v])
    elif op == 1:
        col = pa.array([None if rng.random() < 0.01 else float(x) for x in v], pa.float64())
    elif op == 2:
        col = pa.array(np.round(v.astype(np.float64)).astype(np.int64))
    elif op == 3:
        col = pa.array(v.astype(np.float64) * float(rng.choice([0.0, -1.0, 1e3, 1 / 6])))
    elif op == 4:
        col = pa.array(np.round(v.astype(np.float64)))
    else:
        pq.write_table(t.drop([name]), path)
        return
    pq.write_table(t.set_column(t.column_names.index(name), name, col), path)


# --- running --------------------------------------------------------------------------------

_SPILLS: list = []


def _track_spills() -> None:
    """Spills of in-process runs are closed after each (the CLI leaves them to exit)."""
    if getattr(columns_mod.Spill, "_fuzz_tracked", False):
        return
    init = columns_mod.Spill.__init__

    def tracked(self, *a, **kw) -> None:  # noqa: ANN001, ANN002, ANN003
        init(self, *a, **kw)
        _SPILLS.append(self)

    columns_mod.Spill.__init__ = tracked  # type: ignore[method-assign]
    columns_mod.Spill._fuzz_tracked = True  # type: ignore[attr-defined]


def run_cli(argv: list[str]) -> tuple[int | None, str]:
    """(exit status, stderr) of `fogsf ARGV` in-process; (None, the traceback) when an
    exception leaves `main`."""
    _track_spills()
    logging.disable(logging.WARNING)  # nptdms' warnings on damaged files
    err = io.StringIO()
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
            rc = main(argv)
    except SystemExit as e:
        rc = int(e.code) if isinstance(e.code, int) else 1
    except Exception:  # noqa: BLE001 - what the fuzzing looks for
        return None, traceback.format_exc()
    finally:
        while _SPILLS:
            _SPILLS.pop().close()
    return rc, err.getvalue()


def fuzz(root: Path, files: int, seed: int, say: Callable[[str], None] | None = None
         ) -> tuple[Counter, list[tuple[str, str]]]:
    """Run `files` corrupted logs: (counts by kind and outcome, [(file, traceback)])."""
    bases = make_bases(root / "base", seed)
    kinds = list(bases)
    rng = np.random.default_rng(seed)
    counts: Counter = Counter()
    tracebacks: list[tuple[str, str]] = []
    for k in range(files):
        kind = kinds[int(rng.integers(0, len(kinds)))]
        dst = root / "runs" / f"{k:06d}"
        path = corrupt(kind, bases[kind], dst, rng)
        argv = ["inspect", str(path), "--window-s", "10"]
        if rng.random() < 0.2:
            argv += ["--sample-rate-hz", "10"]
        if rng.random() < 0.2:
            argv.append("--json")
        rc, text = run_cli(argv)
        counts[(kind, "traceback" if rc is None else rc)] += 1
        if rc == 2:
            counts[("rule", refusal_rule(text))] += 1
        if rc is None or rc not in (0, 2) or (rc == 2 and not one_line(text)):
            tracebacks.append((str(path), text))
        else:
            shutil.rmtree(dst, ignore_errors=True)
        if say is not None and (k + 1) % 500 == 0:
            say(f"{k + 1} files, {len(tracebacks)} tracebacks")
    return counts, tracebacks


def one_line(err: str) -> bool:
    """A refusal is one line of stderr (after any read notes), with no traceback."""
    return "Traceback" not in err and sum(": error: " in ln for ln in err.splitlines()) == 1


def refusal_rule(err: str) -> str:
    """The rule a refusal names: the words after the file (and line) in its error line."""
    line = next((ln for ln in err.splitlines() if ": error: " in ln), "")
    parts = [p.strip() for p in line.split(": ")]
    parts = [p for p in parts[2:] if not p.startswith(("line ", "/", "row "))]
    return parts[0][:40] if parts else "?"


def _where(tb: str) -> str:
    """The last frame and the exception line of a traceback."""
    lines = [ln for ln in tb.strip().splitlines() if ln.strip()]
    frames = [ln.strip() for ln in lines if ln.strip().startswith("File ")]
    return f"{frames[-1] if frames else '?'} | {lines[-1] if lines else '?'}"


if __name__ == "__main__":
    import argparse
    import tempfile

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--files", type=int, default=10_000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--keep", default=None, help="folder to keep the failing files in")
    a = ap.parse_args()
    root = Path(a.keep or tempfile.mkdtemp(prefix="fogsf-fuzz-"))
    counts, bad = fuzz(root, a.files, a.seed, say=lambda s: print(s, file=sys.stderr,
                                                                 flush=True))
    for key, c in sorted(counts.items(), key=str):
        print(f"{key[0]:8s} {key[1]!s:10s} {c}")
    print(f"{a.files} corrupted files, {len(bad)} tracebacks (or exits other than 0 and 2)")
    for where, c in Counter(_where(tb) for _, tb in bad).most_common():
        print(f"  {c:5d}  {where}")
    if not a.keep:
        shutil.rmtree(root, ignore_errors=True)
    sys.exit(1 if bad else 0)
