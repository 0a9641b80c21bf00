"""The report's picture in docs/fleet.md (docs/img/fleet-report.png): `fogsf fleet report` of a
made-up line of UNITS units (benchmarks/probes/fleet_scale.py's units: real summaries of
simulated units, figures drawn around a line, one unit in 50 defective), `--plateau-units N`
units calibrated on plateau tables beside them, `--spec-ppm`, rendered by headless Chromium
(as tests/test_fleet_report.py renders it).

    python -m benchmarks.probes.fleet_report_shot --units 120 --out docs/img/fleet-report.png
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

from benchmarks.probes.fleet_scale import base_summaries, synthetic_unit
from fogsf.cli.main import main as cli
from fogsf.fleet.store import open_store
from tests.test_fleet_report import CHROMIUM, _chromium


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--units", type=int, default=120)
    ap.add_argument("--plateau-units", type=int, default=0)
    ap.add_argument("--spec-ppm", type=float, default=15.0)
    ap.add_argument("--size", default="1100,1800", help="the window, px: width,height")
    ap.add_argument("--keep", type=int, default=1340,
                    help="rows of the picture kept, px (the window is rendered taller: the "
                         "last ~130 px of a headless window stay blank)")
    ap.add_argument("--base-cache", default="out/fleet-scale-base.json")
    ap.add_argument("--out", default="docs/img/fleet-report.png")
    a = ap.parse_args(argv)
    if CHROMIUM is None:
        raise SystemExit("headless Chromium is not installed (scripts/toolchain.sh)")
    base = base_summaries(Path(a.base_cache).resolve())
    out = Path(a.out).resolve()
    home = Path.cwd()
    with tempfile.TemporaryDirectory(prefix="fleet-shot-") as t:
        tmp = Path(t)
        os.chdir(tmp)  # the report's title is the fleet as given: line.fleet
        fleet = "line.fleet"
        with open_store(fleet) as store:
            for i in range(a.units):
                store.add(synthetic_unit(i, base))
        for i in range(a.plateau_units):  # units calibrated on a rate table's plateaus
            table = tmp / f"P{i}" / "table.csv"
            assert cli(["simulate", "--plateaus", "--random-gyro", "17", "--effect",
                        "open_loop=0.2", "--seed", str(i + 1), "--out", str(table)]) == 0
            assert cli(["fleet", "add", fleet, "--unit", f"PL{i:03d}", "--train",
                        str(table)]) == 0
        report = tmp / "report"
        assert cli(["fleet", "report", fleet, "--out", str(report), "--spec-ppm",
                    str(a.spec_ppm)]) == 0
        done = _chromium([f"--screenshot={out}", f"--window-size={a.size}",
                          "--hide-scrollbars", (report / "index.html").as_uri()], tmp)
        if not out.is_file():
            raise SystemExit(f"no screenshot: {done.stderr[-2000:]}")
        os.chdir(home)
    from PIL import Image  # matplotlib's dependency

    with Image.open(out) as img:
        img.crop((0, 0, img.width, min(a.keep, img.height))).save(out)
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
