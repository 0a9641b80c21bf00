"""Logs as rigs and spreadsheets write them: BOM, ; and tab, the rig's column names, several
gyro axes; every refusal names the option that fixes it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from fogsf.cli.main import main
from fogsf.errors import UserError
from fogsf.logs.chamber_log import LogError
from fogsf.logs.logio import read_log
from fogsf.logs.read.dialect import Dialect

SHORT = ["--scenario", "paper", "--start-c", "15", "--stop-c", "25", "--ramp-rate", "1",
         "--seed", "3"]
RIG = {"time_s": "t", "temp_c": "temperature", "table_rate_dps": "table", "gyro_dps": "omega"}


@pytest.fixture(scope="module")
def plain(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("dialects") / "plain.csv"
    assert main(["simulate", *SHORT, "--out", str(out)]) == 0
    return out


def _same(a, b) -> None:  # noqa: ANN001 - ChamberLogs
    for k, v in a.columns().items():
        assert np.array_equal(v, b.columns()[k]), k


def _rewrite(src: Path, dst: Path, header: list[str] | None = None, delim: str = ",",
             bom: bool = False) -> Path:
    lines = src.read_text().splitlines()
    if header is not None:
        lines[0] = ",".join(header)
    text = "\n".join(line.replace(",", delim) for line in lines) + "\n"
    dst.write_text(("\ufeff" if bom else "") + text, encoding="utf-8")
    return dst


def test_bom_semicolon_and_tab_read_as_the_plain_log(plain: Path, tmp_path: Path) -> None:
    ref = read_log(plain)
    _same(read_log(_rewrite(plain, tmp_path / "bom.csv", bom=True)), ref)
    semi = _rewrite(plain, tmp_path / "semi.csv", delim=";", bom=True)
    _same(read_log(semi), ref)
    _same(read_log(semi, Dialect(delimiter=";")), ref)
    _same(read_log(_rewrite(plain, tmp_path / "tab.csv", delim="\t")), ref)
    assert main(["inspect", str(semi), "--delimiter", ";"]) == 0


def test_a_decimal_comma_is_refused_with_a_hint(plain: Path, tmp_path: Path) -> None:
    semi = _rewrite(plain, tmp_path / "semi.csv", delim=";")
    lines = semi.read_text().splitlines()
    lines[5] = lines[5].replace(".", ",", 1)
    semi.write_text("\n".join(lines) + "\n")
    with pytest.raises(LogError, match=r"line 6: non-numeric cell.*decimal comma"):
        read_log(semi)


def test_the_rigs_column_names_are_mapped(plain: Path, tmp_path: Path, capsys) -> None:
    header = plain.read_text().splitlines()[0].split(",")
    rig = _rewrite(plain, tmp_path / "rig.csv", [RIG.get(h, h) for h in header])
    with pytest.raises(LogError, match="missing required column.*--columns time_s=NAME"):
        read_log(rig)
    arg = ",".join(f"{k}={v}" for k, v in RIG.items())
    _same(read_log(rig, Dialect(columns=Dialect.parse_columns(arg))), read_log(plain))
    mapping = tmp_path / "columns.json"
    mapping.write_text(json.dumps(RIG))
    assert main(["inspect", str(rig), "--columns", str(mapping), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["samples"] == len(read_log(plain))
    assert main(["inspect", str(rig), "--columns", "time_s=tt"]) == 2
    assert "--columns names 'tt' for time_s" in capsys.readouterr().err
    with pytest.raises(UserError, match="not a column of the format"):
        Dialect.parse_columns("speed=omega")


def test_one_axis_of_a_three_axis_log(plain: Path, tmp_path: Path, capsys) -> None:
    log = read_log(plain)
    cols = {k: v for k, v in log.columns().items() if k != "gyro_dps"}
    axes = {"gyro_x_dps": log.gyro_dps, "gyro_y_dps": log.gyro_dps * (1 + 300e-6),
            "gyro_z_dps": log.gyro_dps * (1 - 200e-6)}
    names = [*cols, *axes]
    data = np.column_stack([*cols.values(), *axes.values()])
    imu = tmp_path / "imu.csv"
    with open(imu, "w") as f:
        f.write(",".join(names) + "\n")
        np.savetxt(f, data, delimiter=",", fmt="%.10g")
    with pytest.raises(LogError, match=r"--gyro-column gyro_x_dps \(or --axis x\)"):
        read_log(imu)
    y = read_log(imu, Dialect(gyro_column="gyro_y_dps"))
    assert np.allclose(y.gyro_dps, axes["gyro_y_dps"], rtol=1e-9)
    assert "gyro_x_dps" in y.extra  # the other axes are kept, not dropped
    out = tmp_path / "m"
    assert main(["train", "--train", str(imu), "--axis", "z", "--model", "poly",
                 "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["train", "--train", str(imu), "--axis", "z", "--gyro-column", "gyro_x_dps",
                 "--model", "poly", "--out", str(out)]) == 2
    assert "--axis or --gyro-column" in capsys.readouterr().err


def test_a_log_that_never_reaches_20_c_takes_the_nearest_temperature(tmp_path: Path,
                                                                       capsys) -> None:
    warm = tmp_path / "warm.csv"
    assert main(["simulate", "--scenario", "paper", "--start-c", "30", "--stop-c", "40",
                 "--ramp-rate", "1", "--out", str(warm)]) == 0
    capsys.readouterr()
    assert main(["inspect", "--json", str(warm)]) == 0
    out = capsys.readouterr()
    s = json.loads(out.out)
    lo, hi = s["temp_range_c"]
    assert lo - 0.5 <= s["ref_temp_c"] <= lo + 1.0  # the nearest to 20 C its windows hold
    assert "nearest temperature" in out.err and "--ref-sf" in out.err
    assert main(["inspect", "--json", str(warm), "--ref-temp-c", "35"]) == 0
    s35 = json.loads(capsys.readouterr().out)
    assert s35["ref_temp_c"] == 35.0 and s35["ref_sf_ratio"] != s["ref_sf_ratio"]
    assert main(["inspect", str(warm), "--ref-sf", "1.0"]) == 0


# --- every dialect reads to the plain log's numbers, and says how it was read ----------------

def _inspect_json(capsys, *argv: str) -> tuple[dict, str]:
    """inspect --json's result and its stderr, without the note on a moving start (about the
    run, not how the file is written)."""
    assert main(["inspect", "--json", *argv]) == 0
    out = capsys.readouterr()
    err = "".join(line for line in out.err.splitlines(keepends=True)
                  if "starts while the board temperature moves" not in line)
    return json.loads(out.out), err


def _refused(capsys, *argv: str) -> str:
    assert main(list(argv)) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    return err


def _renamed(text: str, names: dict[str, str]) -> str:
    head, rest = text.split("\n", 1)
    return ",".join(names.get(h, h) for h in head.split(",")) + "\n" + rest


DIALECTS = {  # name -> (rewrite of the plain text, encoding, options, the stderr note)
    "bom": (lambda t: t, "utf-8-sig", [], "byte-order mark skipped"),
    "semicolon": (lambda t: t.replace(",", ";"), "utf-8", [], "separated by ';'"),
    "tab": (lambda t: t.replace(",", "\t"), "utf-8", [], "separated by tab"),
    "semicolon-given": (lambda t: t.replace(",", ";"), "utf-8", ["--delimiter", ";"], None),
    "excel-decimal-comma": (  # BOM, CRLF, ';' between cells, ',' in numbers
        lambda t: t.replace(",", ";").replace(".", ",").replace("\n", "\r\n"), "utf-8-sig",
        ["--decimal-comma"], "decimal comma"),
    "rig-names": (lambda t: _renamed(t, RIG), "utf-8",
                  ["--columns", ",".join(f"{k}={v}" for k, v in RIG.items())],
                  "t -> time_s"),
}


@pytest.mark.parametrize("name", list(DIALECTS))
def test_each_dialect_gives_the_plain_logs_numbers(name: str, plain: Path, tmp_path: Path,
                                                   capsys) -> None:
    want, err = _inspect_json(capsys, str(plain))
    assert err == ""  # the plain format is read without comment
    rewrite, encoding, opts, note = DIALECTS[name]
    p = tmp_path / f"{name}.csv"
    p.write_text(rewrite(plain.read_text()), encoding=encoding, newline="")
    got, err = _inspect_json(capsys, str(p), *opts)
    assert got == want
    if note is None:
        assert err == ""
    else:
        assert err.startswith(f"fogsf: read {p}: ") and note in err, err


@pytest.mark.parametrize("suffix", [".json", ".toml"])
def test_a_mapping_file_beside_the_logs_applies_and_is_named(suffix: str, plain: Path,
                                                             tmp_path: Path, capsys) -> None:
    want, _ = _inspect_json(capsys, str(plain))
    rig = tmp_path / "rig.csv"
    rig.write_text(_renamed(plain.read_text(), RIG))
    mapping = tmp_path / f"fogsf-columns{suffix}"
    mapping.write_text(json.dumps(RIG) if suffix == ".json"
                       else "".join(f'{k} = "{v}"\n' for k, v in RIG.items()))
    got, err = _inspect_json(capsys, str(rig))
    assert got == want and f"({mapping})" in err, err
    # the same file given by path, for a log in another folder
    other = tmp_path / "other"
    other.mkdir()
    (other / "rig.csv").write_text(rig.read_text())
    assert _inspect_json(capsys, str(other / "rig.csv"), "--columns", str(mapping))[0] == want
    # --columns replaces the file beside the log (here with a column the log lacks)
    err = _refused(capsys, "inspect", str(rig), "--columns", "time_s=seconds")
    assert "--columns names 'seconds' for time_s" in err


def test_a_mapping_file_beside_the_logs_and_a_plain_log(plain: Path, tmp_path: Path,
                                                       capsys) -> None:
    p = tmp_path / "plain.csv"
    p.write_text(plain.read_text())
    (tmp_path / "fogsf-columns.json").write_text(json.dumps({"temp_c": "board"}))
    # a log already in the format's names is read as it is, and that is said
    assert main(["inspect", str(p), "--json"]) == 0
    assert "fogsf-columns.json not applied" in capsys.readouterr().err
    # a log in neither the format's names nor the file's is refused, naming the file
    header = plain.read_text().splitlines()[0]
    q = tmp_path / "other.csv"
    q.write_text(plain.read_text().replace(header, header.replace("temp_c", "t_board", 1), 1))
    err = _refused(capsys, "inspect", str(q))
    assert "fogsf-columns.json names 'board' for temp_c" in err
    (tmp_path / "fogsf-columns.toml").write_text('temp_c = "board"\n')
    assert "both fogsf-columns.json and fogsf-columns.toml" in _refused(capsys, "inspect",
                                                                        str(p))


@pytest.mark.parametrize(
    ("body", "opts", "needle"),
    [
        ("time_s;temp_c,table_rate_dps;gyro_dps\n0;20;10;10\n", [],
         "holds ',' and ';'; give --delimiter"),
        ("time_s temp_c table_rate_dps gyro_dps\n0 20 10 10\n", [], "write the log with one"),
        ("time_s\n0\n", [], "--columns time_s=NAME"),
        ("time_s,temp_c,table_rate_dps,gyro_dps\n0,20,10,10\n", ["--decimal-comma"],
         "decimal comma with ',' cells"),
        ("time_s;temp_c;table_rate_dps;gyro_dps\n0;20,5;10;10\n", [],
         "give --decimal-comma"),
        ("time_s,temp_c,table_rate_dps,gyro_dps\n0,20,5,10,10\n", [], "--decimal-comma"),
        ("time_s,temp_c,table_rate_dps,gyro_dps\n0,20,10,10\n",
         ["--decimal-comma", "--delimiter", ","], "--decimal-comma needs"),
        ("t,temp_c,table_rate_dps,gyro_dps\n0,20,10,10\n", ["--columns", "time_s=t,temp_c=t"],
         "'t' is mapped to two names"),
        ("time_s,temp_c,table_rate_dps,gyro_dps\n0,20,10,10\n", ["--columns", "bad.toml"],
         "bad.toml: cannot read the column mapping"),
    ],
)
def test_refusals_name_the_option_that_fixes_them(body: str, opts: list[str], needle: str,
                                                  tmp_path: Path, capsys) -> None:
    p = tmp_path / "x.csv"
    p.write_text(body)
    assert needle in _refused(capsys, "inspect", str(p), *opts)


# --- a log that never reaches 20 C: every command that needs the reference takes --ref-sf ----

def test_ref_sf_from_a_longer_run_makes_a_cold_log_usable(plain: Path, tmp_path: Path,
                                                          capsys) -> None:
    from fogsf.models import samples

    cold = tmp_path / "cold.csv"
    assert main(["simulate", "--scenario", "paper", "--start-c", "-30", "--stop-c", "-10",
                 "--ramp-rate", "2", "--seed", "4", "--out", str(cold)]) == 0
    capsys.readouterr()
    model = samples.random_model(3, 4, 1, 8, decimation=10, seed=6)
    model.save(tmp_path / "m")
    argvs = {"inspect": ["inspect", str(cold)],
             "train": ["train", "--train", str(cold), "--model", "poly", "--out",
                       str(tmp_path / "poly")],
             "replay": ["replay", str(tmp_path / "m"), str(cold), "--out",
                        str(tmp_path / "c.csv"), "--build-dir", str(tmp_path / "kernels")]}
    for cmd in ("inspect", "train", "replay"):  # the SF at the nearest temperature held
        assert main(argvs[cmd]) == 0, cmd
        got = capsys.readouterr()
        err = got.err
        assert "nearest temperature" in err and "--ref-sf" in err, (cmd, err)
        if cmd == "replay":  # "before" names the reference it took: the log's own
            about = got.out.split("before: about ")[1].split(";")[0]
            assert about.startswith("the log's SF at -1") and "vs nominal" in about, about
    ref = _inspect_json(capsys, str(plain))[0]["ref_sf_ratio"]
    got = _inspect_json(capsys, str(cold), "--ref-sf", repr(ref))[0]
    assert got["ref_sf_ratio"] == ref and got["metrics"]["rms_ppm"] > 0
    assert main([*argvs["train"], "--ref-sf", repr(ref)]) == 0
    metrics = json.loads((tmp_path / "poly" / "metrics.json").read_text())
    assert metrics["ref_sf_ratio"] == ref
    assert metrics["train"]["after"]["rms_ppm"] < metrics["train"]["before"]["rms_ppm"]
    assert main([*argvs["replay"], "--ref-sf", repr(ref)]) == 0
    assert "before: about --ref-sf" in capsys.readouterr().out


# --- the command line: version, and every --help ends with examples that parse -------------

def test_version(capsys) -> None:
    from importlib.metadata import version

    with pytest.raises(SystemExit) as ei:
        main(["--version"])
    assert ei.value.code == 0
    assert capsys.readouterr().out.strip() == f"fogsf {version('fogsf')}"


def test_every_help_ends_with_examples_that_parse(capsys) -> None:
    import shlex

    from fogsf.cli.main import COMMANDS, build_parser

    parser = build_parser()
    for argv in ([], *([c] for c in COMMANDS)):
        with pytest.raises(SystemExit):
            main([*argv, "--help"])
        text = capsys.readouterr().out.rstrip()
        tail = text.rsplit("\n\n", 1)[-1].splitlines()
        assert tail[0].strip().lower() in ("example:", "examples:"), (argv, tail)
        for line in tail[1:]:
            for cmd in line.split("#")[0].split("&&"):
                words = shlex.split(cmd)
                assert words[0] == "fogsf", (argv, line)
                parser.parse_args(words[1:])  # exits (fails the test) on a bad example


def test_quoted_cells_are_read_as_csv(plain: Path, tmp_path: Path, capsys) -> None:
    lines = plain.read_text().splitlines()
    quoted = tmp_path / "quoted.csv"
    quoted.write_text("\n".join(",".join(f'"{c}"' for c in line.split(",")) for line in lines)
                      + "\n")
    _same(read_log(quoted), read_log(plain))
    assert main(["inspect", str(quoted), "--axis", "z"]) == 2  # no gyro_z_dps: named
    assert "gyro_z_dps" in capsys.readouterr().err
    bad = tmp_path / "thousands.csv"
    bad.write_text(lines[0] + "\n" + lines[1].replace(",", ',"1,0",', 1) + "\n")
    with pytest.raises(LogError, match="line 2: delimiter inside a quoted cell"):
        read_log(bad)
    broken = tmp_path / "broken.csv"
    broken.write_text('"time_s,temp_c\n')
    with pytest.raises(LogError, match="bad quoting"):
        read_log(broken)
