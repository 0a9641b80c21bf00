"""fogsf fleet report: a static folder that opens from disk, user strings shown as text,
rendered by headless Chromium into a screenshot that is not blank."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from fogsf.cli.main import main
from fogsf.fleet.report import SORT_JS
from fogsf.fleet.store import open_store
from tests.fleet_units import fake_record

EVIL = "<script>alert(1)</script>"
CHROMIUM = next((c for c in ("/usr/bin/chromium", shutil.which("chromium") or "",
                             shutil.which("chromium-browser") or "") if c and Path(c).exists()),
                None)


def _fleet(tmp_path: Path) -> str:
    """Six made-up units, one named EVIL with a path to match, one far from the others."""
    fleet = str(tmp_path / "line.fleet")
    with open_store(fleet) as store:
        for i, sn in enumerate([EVIL, "SN001", "SN002", "SN003", "SN004", "SN005"]):
            rec = fake_record(sn, seed=i)
            rec.logs[0].path = f"/lab/{EVIL}/run.csv" if i == 0 else rec.logs[0].path
            rec.figures["response_ppm"] = {"soak": 10.0 + (i % 3), "ramp": -5.0 + 0.5 * i}
            if sn == "SN005":
                rec.figures["response_ppm"]["soak"] = 400.0
            store.add(rec)
    return fleet


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    tmp = tmp_path_factory.mktemp("report")
    assert main(["fleet", "report", _fleet(tmp), "--out", str(tmp / "rep")]) == 0
    return tmp / "rep"


def test_report_is_static_and_escapes_user_strings(report: Path) -> None:
    pages = [report / "index.html", *sorted((report / "units").glob("*.html"))]
    assert len(pages) == 7
    for page in pages:
        text = page.read_text(encoding="utf-8")
        assert EVIL not in text
        # the index's one script is the report's own sorter, no user string in it
        scripts = re.findall(r"<script[^>]*>(.*?)</script>", text, flags=re.S | re.I)
        assert scripts == ([SORT_JS] if page.name == "index.html" else [])
        assert text.lower().count("<script") == len(scripts)
        for ref in re.findall(r'(?:src|href)="([^"]*)"', text):
            assert "://" not in ref and not ref.startswith("/"), ref  # nothing fetched
            assert (page.parent / ref).is_file(), f"{page.name} links {ref}, not written"
    index = (report / "index.html").read_text(encoding="utf-8")
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in index
    body = index.split("<tbody>")[1].split("</tbody>")[0]
    assert body.count("<tr") == 6  # a row per unit
    flagged = [row for row in index.split("<tr") if 'class="flag"' in row]
    assert len(flagged) == 1 and "SN005" in flagged[0] and "soak" in flagged[0]
    evil_page = (report / "units" / "unit-000.html").read_text(encoding="utf-8")
    assert f"/lab/{EVIL}/run.csv".replace("<", "&lt;").replace(">", "&gt;") in evil_page


def _chromium(args: list[str], tmp_path: Path) -> subprocess.CompletedProcess:
    assert CHROMIUM is not None
    return subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
         "--no-first-run", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", f"--user-data-dir={tmp_path / 'profile'}", *args],
        capture_output=True, text=True, timeout=120)


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (scripts/toolchain.sh "
                    "installs Debian's chromium): the report is not rendered")
def test_report_renders_in_headless_chromium(report: Path, tmp_path: Path) -> None:
    import matplotlib.image

    shot = tmp_path / "shot.png"
    url = (report / "index.html").resolve().as_uri()
    done = _chromium([f"--screenshot={shot}", "--window-size=1200,900", url], tmp_path)
    assert shot.is_file(), done.stderr[-2000:]
    img = np.asarray(matplotlib.image.imread(shot))[..., :3]
    assert img.shape[0] >= 800 and img.shape[1] >= 1100
    assert float(img.std()) > 0.05, "the screenshot is blank"
    assert np.mean(np.any(np.abs(img - img[0, 0]) > 0.1, axis=-1)) > 0.02  # drawn, not one colour
    dom = _chromium(["--dump-dom", url], tmp_path).stdout
    assert "Fleet" in dom and "&lt;script&gt;alert(1)&lt;/script&gt;" in dom
    assert dom.lower().count("<script") == 1  # the sorter: no script element of the name
