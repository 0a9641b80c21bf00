"""`--spec-ppm` (list, report) and the report of a line's many units: the summary first,
the units out of family and out of spec first, a legend on every plot, the sortable table;
500 units written in under a minute and loaded by headless Chromium in under 2 s."""

from __future__ import annotations

import re
import time
from pathlib import Path

import pytest

from fogsf.cli.main import main
from fogsf.fleet.records import UnitRecord, interval_of, spec_verdict
from fogsf.fleet.report import SORT_JS
from fogsf.fleet.store import open_store
from tests.fleet_units import fake_record
from tests.test_fleet_report import CHROMIUM, _chromium


def _with_interval(lo: float | None, hi: float | None) -> UnitRecord:
    rec = fake_record("SN1")
    rec.interval = None if lo is None else dict(rec.interval or {}, rms_lo_ppm=lo,
                                                 rms_hi_ppm=hi)
    return rec


@pytest.mark.parametrize(("lo", "hi", "spec", "want"), [
    (8.0, 10.0, 10.0, "within spec"),  # the top at the spec: within
    (8.0, 10.0, 12.0, "within spec"),
    (8.0, 10.0, 9.0, "unsure"),  # straddles it
    (8.0, 10.0, 8.0, "unsure"),  # the bottom at the spec: not over it
    (8.0, 10.0, 7.9, "out of spec"),
    (None, None, 10.0, "unsure"),  # no test log, no interval
    (8.0, 0.0, 10.0, "unsure"),  # no interval stated
    (8.0, float("nan"), 10.0, "unsure"),
])
def test_spec_verdict_from_the_units_interval(lo: float | None, hi: float | None,
                                              spec: float, want: str) -> None:
    assert spec_verdict(_with_interval(lo, hi), spec) == want


def test_a_unit_under_the_prior_is_judged_on_the_priors_interval() -> None:
    metrics = {"test": {"after": {"rms_ppm": 9.0}}, "noise_floor_ppm": 6.0,
               "rate_transfer": {"rms_interval_ppm": [5.0, 30.0], "noise_floor_ppm": 6.0},
               "prior": {"interval_ppm": [6.0, 11.0]}}
    iv = interval_of(metrics)
    assert iv is not None and (iv["rms_lo_ppm"], iv["rms_hi_ppm"], iv["source"]) == (
        6.0, 11.0, "prior")
    del metrics["prior"]
    iv = interval_of(metrics)
    assert iv is not None and (iv["rms_hi_ppm"], iv["source"]) == (30.0, "rate transfer")


def _unit(i: int, n: int) -> UnitRecord:
    """Unit i of a made-up line of n: one in 50 far off in one feature, every 10th with an
    interval over 20 ppm (out of spec at 15), every 7th else straddling it (unsure)."""
    rec = fake_record(f"SN{i}", seed=i)
    rec.figures["response_ppm"] = {"soak": 10.0 + (i * 37 % 11) / 5.0,
                                   "ramp": -5.0 + (i * 53 % 13) / 6.0
                                   + (80.0 if i % 50 == 24 else 0.0)}
    assert rec.interval is not None
    if i % 10 == 9:
        rec.interval.update(rms_lo_ppm=21.0, rms_hi_ppm=30.0)
    elif i % 7 == 6:
        rec.interval.update(rms_lo_ppm=12.0, rms_hi_ppm=18.0)
    rec.created_utc = f"2026-{1 + i * 11 // n:02d}-{1 + i % 28:02d}T10:00:00Z"
    return rec


def _fleet(path: Path, n: int) -> str:
    fleet = str(path / "line.fleet")
    with open_store(fleet) as store:
        for i in range(n):
            store.add(_unit(i, n))
    return fleet


def test_list_says_each_units_spec(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    fleet = _fleet(tmp_path, 20)
    assert main(["fleet", "list", fleet, "--spec-ppm", "15"]) == 0
    out = capsys.readouterr().out
    rows = {ln.split()[0]: ln for ln in out.splitlines() if ln.startswith("SN")}
    assert rows["SN9"].endswith("out of spec") and rows["SN6"].endswith("unsure")
    assert rows["SN0"].endswith("within spec")
    assert "spec 15 ppm (test RMS): 16 within, 2 out of spec, 2 unsure" in out
    assert main(["fleet", "list", fleet, "--spec-ppm", "15", "--json"]) == 0
    assert '"spec": "out of spec"' in capsys.readouterr().out
    assert main(["fleet", "list", fleet, "--spec-ppm", "-1"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--spec-ppm must be a positive number" in err and "\n" not in err


@pytest.mark.slow
def test_the_report_of_many_units_leads_with_the_summary(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from matplotlib.figure import Figure

    legends: dict[str, list[bool]] = {}
    save = Figure.savefig

    def saved(fig: Figure, path: object, *args: object, **kwargs: object) -> None:
        legends[Path(str(path)).name] = [ax.get_legend() is not None for ax in fig.axes]
        save(fig, path, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", saved)
    n = 80
    fleet = _fleet(tmp_path, n)
    assert main(["fleet", "report", fleet, "--out", str(tmp_path / "rep"),
                 "--spec-ppm", "15"]) == 0
    index = (tmp_path / "rep" / "index.html").read_text(encoding="utf-8")
    # every plot, each of its axes, has a legend; the trends over serial number and date
    assert {"trend_serial.png", "trend_date.png", "sf_vs_temperature.png"} <= set(legends)
    assert all(all(v) and v for v in legends.values()), legends
    for name in legends:
        assert f'src="{name}"' in index and (tmp_path / "rep" / name).is_file()
    # the summary before the plots, the plots before the table
    assert index.index('id="summary"') < index.index("<img") < index.index('class="sortable"')
    summary = index.split('id="summary"')[1].split("</section>")[0]
    far = [i for i in range(n) if i % 50 == 24]
    out_spec = [i for i in range(n) if i % 10 == 9]
    assert f"out of family (unlike the line)</th><td>{len(far)}<" in summary
    assert f"out of spec (15 ppm test RMS)</th><td>{len(out_spec)}<" in summary
    for i in far + out_spec:
        assert f">SN{i}</a>" in summary
    # the table: those units first, then the others in serial order; sortable
    body = index.split("<tbody>")[1].split("</tbody>")[0]
    names = re.findall(r">(SN\d+)</a>", body)
    first = {f"SN{i}" for i in far + out_spec}
    assert len(names) == n and set(names[:len(first)]) == first
    unsure = [f"SN{i}" for i in range(n) if i % 7 == 6 and f"SN{i}" not in first]
    assert names[len(first):len(first) + len(unsure)] == unsure  # then unsure, by serial
    assert names[len(first) + len(unsure):][:3] == ["SN0", "SN1", "SN2"]
    assert '<table class="sortable"><thead>' in index and f"<script>{SORT_JS}</script>" in index
    page = re.search(r'href="(units/unit-\d+\.html)">SN9</a>', body)
    assert page is not None
    unit = (tmp_path / "rep" / page.group(1)).read_text(encoding="utf-8")
    assert "<svg" in unit and ">before</text>" in unit and ">after</text>" in unit
    assert "spec 15 ppm test RMS: <b>out of spec</b>" in unit


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (scripts/toolchain.sh "
                    "installs Debian's chromium): the report is not rendered")
def test_a_report_of_500_units_is_written_in_a_minute_and_loads_in_2_s(tmp_path: Path) -> None:
    n = 500
    fleet = _fleet(tmp_path, n)
    t0 = time.perf_counter()
    assert main(["fleet", "report", fleet, "--out", str(tmp_path / "rep"),
                 "--spec-ppm", "15"]) == 0
    took = time.perf_counter() - t0
    assert took < 60.0
    url = (tmp_path / "rep" / "index.html").resolve().as_uri()
    dom = _chromium(["--dump-dom", url], tmp_path).stdout
    loaded = re.search(r'data-loaded-ms="(\d+)"', dom)  # the page's own load event
    assert loaded is not None, dom[:2000]
    assert int(loaded.group(1)) < 2000
    print(f"report of {n} units written in {took:.1f} s, loaded in {loaded.group(1)} ms")
    table = dom.split('<table class="sortable">')[1].split("</table>")[0]
    assert table.split("<tbody>")[1].count("<tr") == n
