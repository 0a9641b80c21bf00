import subprocess
import sys


def test_help_lists_every_command() -> None:
    out = subprocess.run([sys.executable, "-m", "fogsf", "--help"], check=True,
                         capture_output=True, text=True).stdout
    for name in ("simulate", "inspect", "train", "export", "replay", "diagnose"):
        assert name in out


def test_a_negative_range_is_read_as_a_value() -> None:
    from fogsf.trainer.cli import build_parser, join_negative_ranges

    for argv in (["plan", "--range", "-20:60", "--out", "p"],
                 ["plan", "--range=-20:60", "--out", "p"]):
        args = build_parser().parse_args(join_negative_ranges(argv))
        assert args.range == (-20.0, 60.0)
    args = build_parser().parse_args(join_negative_ranges(
        ["plan", "--range", "-40.5:-1e1", "--envelope-rate", "0.2:2", "--out", "p"]))
    assert args.range == (-40.5, -10.0) and args.envelope_rate == (0.2, 2.0)


def test_train_help_describes_the_bank_the_code_fits() -> None:
    from fogsf.trainer.cli import build_parser
    from fogsf.trainer.models.lag_bank import CURVED_MAX_TAU_S
    from fogsf.trainer.models.least_squares import TAU_GRID_S

    train = build_parser()._subparsers._group_actions[0].choices["train"]
    text = " ".join(train.format_help().split())
    assert "GCV" not in text
    assert f"lags at {len(TAU_GRID_S)} time constants" in text
    assert f"cubic up to {CURVED_MAX_TAU_S:.0f} s" in text and "one fixed prior" in text
    lo, hi = min(TAU_GRID_S), max(TAU_GRID_S)
    assert lo == 60.0 and hi == 7200.0, "the help says 60 s to 2 h"
