import subprocess
import sys

import pytest


def test_help_lists_every_command() -> None:
    out = subprocess.run([sys.executable, "-m", "fogsf", "--help"], check=True,
                         capture_output=True, text=True).stdout
    for name in ("simulate", "inspect", "train", "export", "replay", "diagnose"):
        assert name in out


@pytest.mark.parametrize("command, argv, key, value", [
    ("plan", ["--range", "-20:60", "--out", "p"], "range", (-20.0, 60.0)),
    ("plan", ["--range=-20:60", "--out", "p"], "range", (-20.0, 60.0)),
    ("plan", ["--range", "-40.5:-1e1", "--out", "p"], "range", (-40.5, -10.0)),
    ("simulate", ["--profile", "steps", "--levels-c", "-20,40,5", "--out", "x.csv"],
     "levels_c", [-20.0, 40.0, 5.0]),
    ("simulate", ["--table", "levels", "--rates-dps", "-10,10", "--out", "x.csv"],
     "rates_dps", [-10.0, 10.0]),
    ("simulate", ["--start-c", "-40", "--out", "x.csv"], "start_c", -40.0),
])
def test_a_value_led_by_a_negative_number_reaches_the_command(
        command: str, argv: list[str], key: str, value: object,
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Through `fogsf`'s main as a user types it: the command gets the value."""
    import importlib

    from fogsf.cli import main as cli

    seen = {}
    mod = importlib.import_module(cli.COMMANDS[command][0])
    monkeypatch.setattr(mod, "run", lambda args: seen.update(vars(args)) or 0)
    assert cli.main([command, *argv]) == 0
    assert seen[key] == value


def test_train_help_describes_the_bank_the_code_fits() -> None:
    from fogsf.cli.main import build_parser
    from fogsf.models.structures.lag_bank import CURVED_MAX_TAU_S
    from fogsf.models.structures.least_squares import TAU_GRID_S
    from fogsf.training.structure.choice import CANDIDATES

    train = build_parser()._subparsers._group_actions[0].choices["train"]
    text = " ".join(train.format_help().split())
    assert "GCV" not in text
    assert f"lags at {len(TAU_GRID_S)} time constants" in text
    assert f"cubic up to {CURVED_MAX_TAU_S:.0f} s" in text and "one fixed prior" in text
    assert "among physics nodes with 1-3 nodes and the bank" in text
    assert CANDIDATES == ("physics1", "physics2", "physics3", "bank")
    lo, hi = min(TAU_GRID_S), max(TAU_GRID_S)
    assert lo == 60.0 and hi == 7200.0, "the help says 60 s to 2 h"


@pytest.mark.parametrize("argv, says", [
    (["plan", "--range", "60:-20", "--out", "p"], "argument --range: expected LO < HI"),
    (["nope"], "invalid choice: 'nope'"),
    (["train", "--train"], "argument --train: expected one argument"),
    (["train", "--train", "a.csv", "--batch-size", "0"],
     "argument --batch-size: expected at least 1"),
    (["train", "--train", "a.csv", "--hidden", "0"], "argument --hidden: expected at least 1"),
    (["train", "--train", "a.csv", "--lr", "-1"], "argument --lr: expected a positive number"),
    (["train", "--train", "a.csv", "--iters", "-5"], "argument --iters: expected 0 or more"),
    (["fleet", "add", "f.fleet", "--unit", "A", "--train", "a.csv", "--gsa-agents", "0"],
     "argument --gsa-agents: expected at least 1"),
])
def test_option_refusals_are_one_line(argv: list[str], says: str,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    from fogsf.cli import main as cli

    with pytest.raises(SystemExit) as e:
        cli.main(argv)
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and says in err[0] and err[0].endswith("--help)"), err
