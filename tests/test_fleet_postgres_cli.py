"""`fogsf fleet` on a PostgreSQL URL that carries a password: no command prints it, and the
read commands neither create a fleet nor write (issue 54). Runs against a real server
(tests/fleet_units.py: FOGSF_TEST_POSTGRES_URL, or Debian's postgresql started for the
session; its trust authentication accepts the password the URL carries)."""

from __future__ import annotations

from pathlib import Path

import pytest

from fogsf.cli.main import main
from fogsf.errors import UserError
from fogsf.fleet.store import open_store
from tests.fleet_units import _postgres

SECRET = "s3cret-Pw"
FAST = ["--structure", "physics", "--iters", "2", "--hysteresis", "off", "--no-progress"]


def _with_password(url: str) -> str:
    """The test server's URL with a user and SECRET as its password."""
    scheme, rest = url.split("://", 1)
    user, _, host = rest.rpartition("@")
    return f"{scheme}://{user or 'postgres'}:{SECRET}@{host}"


@pytest.fixture
def fleet(tmp_path: Path) -> str:
    return _with_password(_postgres(tmp_path))


@pytest.fixture(scope="module")
def log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("logs") / "r2.csv"
    assert main(["simulate", "--scenario", "paper", "--ramp-rate", "2", "--seed", "1",
                 "--start-c", "-20", "--stop-c", "40", "--sample-rate-hz", "1",
                 "--out", str(out)]) == 0
    return out


@pytest.mark.slow
def test_no_command_prints_the_password(fleet: str, log: Path, tmp_path: Path,
                                        capsys: pytest.CaptureFixture) -> None:
    said: list[str] = []

    def run(argv: list[str], code: int) -> None:
        assert main(argv) == code, argv
        out = capsys.readouterr()
        said.append(out.out + out.err)

    run(["fleet", "list", fleet], 2)  # no fleet there yet: a read does not create one
    run(["fleet", "add", fleet, "--unit", "SN1", "--train", str(log), *FAST], 0)
    assert "recorded unit SN1 in postgresql://" in said[-1]
    run(["fleet", "add", fleet, "--unit", "SN1", "--train", str(log), *FAST], 2)
    manifest = tmp_path / "units.csv"
    manifest.write_text(f"unit,train\nSN2,{log}\n")
    run(["fleet", "add-many", fleet, str(manifest), "--workers", "1",
         "--train-options", " ".join(FAST)], 0)
    run(["fleet", "add-many", fleet, str(manifest), "--workers", "1"], 2)  # already there
    run(["fleet", "list", fleet], 0)
    assert "2 unit(s)" in said[-1]
    run(["fleet", "remove", fleet, "SN2"], 0)
    assert "removed unit SN2 from postgresql://" in said[-1]
    run(["fleet", "remove", fleet, "SN2"], 2)
    run(["fleet", "check", fleet], 0)
    for text in said:
        assert SECRET not in text, text
        assert "***@" in text or "postgresql://" not in text, text


def test_read_commands_on_postgres_write_nothing(fleet: str) -> None:
    with pytest.raises(UserError, match="holds no fleet"):
        open_store(fleet, "read")
    with open_store(fleet) as store:  # created by the create mode only
        assert store.location.count(SECRET) == 0
    with open_store(fleet, "read") as store:
        assert store.units() == []
        with pytest.raises(Exception, match="read-only"):
            store.execute("DELETE FROM units")
