"""`fogsf train` and `fogsf replay` on plateau tables (docs/train.md, "Plateau tables"): a
rate response hidden in a population gyro's plateau tables is found and removed, on another
run of the same gyro; a table at one |rate| keeps the rate part off; the commands' refusals.

Hidden effects are drawn with a seeded generator: the gyro (development seeds 0-9999), its
form (an open-loop FOG's sine with its phase scale's temperature coefficient, or a
closed-loop FOG's fractional-power nonlinearity and asymmetry) and strength from the
population's ranges, and the rig's program (set points, top rate, steps)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from fogsf.cli.main import main
from fogsf.models.structures.rate_forms import RateForm
from fogsf.sim import population as pop
from fogsf.sim.effects import EffectConfig
from fogsf.sim.rigs import plateau_tables as pt
from fogsf.training.rate.plateau_model import PlateauRows, fit_plateau_model
from fogsf.training.rate.plateau_train import correct_rows, rms_dph

DRAWS = 4


@dataclass(frozen=True)
class Hidden:
    gyro: int
    kind: str
    effects: tuple[EffectConfig, ...]
    plan: pt.PlateauPlan
    run_seed: int

    def __str__(self) -> str:
        return (f"gyro {self.gyro} {self.kind} {[(e.name, e.strength) for e in self.effects]} "
                f"set points {self.plan.set_points_c} top {self.plan.max_rate_dps} "
                f"steps {self.plan.rate_steps} run seed {self.run_seed}")


def draw(i: int) -> Hidden:
    rng = np.random.default_rng([0x48, i])
    gyro = int(rng.integers(1, 10_000))
    kind = ("open-loop", "closed-loop")[i % 2]
    u = rng.uniform
    if kind == "open-loop":
        effects = (EffectConfig("open_loop", round(u(*pop.OPEN_LOOP_FRACTION), 4),
                                {"tc_ppm_per_c": round(u(*pop.OPEN_LOOP_TC_PPM_PER_C), 1)}),)
    else:
        effects = (EffectConfig("rate_nonlinearity", round(u(*pop.CLOSED_LOOP_NONLIN_PPM), 2),
                                {"exponent": round(u(*pop.CLOSED_LOOP_EXPONENT), 3)}),
                   EffectConfig("asymmetry", round(u(*pop.CLOSED_LOOP_ASYM_PPM), 2)))
    base = u(25.0, 40.0)
    plan = pt.PlateauPlan(set_points_c=tuple(round(base + k * u(5.0, 8.0), 1) for k in range(4)),
                          max_rate_dps=float(round(u(100.0, 200.0))),
                          rate_steps=int(rng.integers(5, 9)), passes=2)
    return Hidden(gyro, kind, effects, plan, int(rng.integers(0, 2**31)))


def rows_of_run(h: Hidden, seed: int) -> PlateauRows:
    cfg = pop.gyro_for_seed(h.gyro)
    cfg.effects.extend(h.effects)
    cfg.seed = seed
    t = pt.plateau_table(pt.run_plateaus(cfg, h.plan))
    c = t.columns
    return PlateauRows(c["gyro_dps"], c["table_rate_dps"] + t.earth_rate_dps, c["temp_c"])


@pytest.mark.slow
@pytest.mark.parametrize("i", range(DRAWS))
def test_a_hidden_rate_response_is_found_and_removed_on_another_run(i: int) -> None:
    h = draw(i)
    train, other = rows_of_run(h, h.run_seed), rows_of_run(h, h.run_seed + 1)
    fit = fit_plateau_model(train)
    linear = fit_plateau_model(train, form=RateForm(1, False, 2, 0))
    after = rms_dph(correct_rows(fit.model, other.temp_c, other.gyro_dps)[0] - other.rate_dps)
    lin = rms_dph(correct_rows(linear.model, other.temp_c, other.gyro_dps)[0]
                  - other.rate_dps)
    # the sine leaves thousands of deg/h to a linear SF, the closed-loop terms tens
    gain = 0.05 if h.kind == "open-loop" else 0.4
    assert fit.form.has_rate_part and fit.model.has_rate_part, f"{h}: {fit.form}"
    assert after <= gain * lin, f"{h}: {after:.2f} deg/h vs linear SF {lin:.2f} ({fit.form})"


@pytest.mark.slow
def test_one_rate_keeps_the_rate_part_off_and_says_so(tmp_path: Path, capsys) -> None:
    h = draw(0)
    cfg = pop.gyro_for_seed(h.gyro)
    cfg.effects.extend(h.effects)
    plan = pt.PlateauPlan(rate_steps=1)
    table = pt.plateau_table(pt.run_plateaus(cfg, plan))
    path, _ = pt.write_plateau_table(tmp_path / "one.csv", table)
    assert main(["train", "--train", str(path), "--out", str(tmp_path / "m")]) == 0
    out = capsys.readouterr().out
    assert "rate part off: the tables hold one |rate| only" in out
    assert "rate_fs_dps" not in (tmp_path / "m" / "stream.json").read_text()


def _simulate(folder: Path, seed: int) -> Path:
    path = folder / "table.csv"
    assert main(["simulate", "--plateaus", "--random-gyro", "17", "--effect", "open_loop=0.25",
                 "--seed", str(seed), "--out", str(path)]) == 0
    return path


@pytest.mark.slow
def test_train_then_replay_gives_the_kernel_the_models_figures(tmp_path: Path, capsys) -> None:
    """train on one run, test on another; replay of the test table through the compiled
    kernel writes a row per plateau and gives the test figure train printed."""
    train, test = _simulate(tmp_path / "a", 1), _simulate(tmp_path / "b", 2)
    model = tmp_path / "m"
    assert main(["train", "--train", str(train), "--test", str(test), "--out", str(model)]) == 0
    out = capsys.readouterr().out
    assert "plateau model: rate terms" in out and "held-out plateaus" in out
    test_line = next(line for line in out.splitlines() if line.strip().startswith("test"))
    after = float(test_line.split("->")[1].split()[0])
    corrected = tmp_path / "corrected.csv"
    assert main(["replay", str(model), str(test), "--out", str(corrected)]) == 0
    out = capsys.readouterr().out
    assert f"after {after:.2f} deg/h RMS" in out, out
    header, *rows = corrected.read_text().splitlines()
    assert header.split(",")[-2:] == ["gyro_corrected_dps", "flags"]
    assert len(rows) == len(test.read_text().splitlines()) - 1


def _refused(capsys, *argv: str) -> str:
    assert main(list(argv)) == 2
    err = [ln for ln in capsys.readouterr().err.strip().splitlines()
           if not ln.startswith("fogsf: read ")]
    assert len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


def test_a_table_beside_a_sample_log_or_with_a_prior_is_refused(tmp_path: Path,
                                                                capsys) -> None:
    table = _simulate(tmp_path / "a", 1)
    sample = tmp_path / "s.csv"
    assert main(["simulate", "--scenario", "paper", "--ramp-rate", "1.0", "--out",
                 str(sample)]) == 0
    capsys.readouterr()
    err = _refused(capsys, "train", "--train", str(table), "--train", str(sample),
                   "--out", str(tmp_path / "m"))
    assert "is a plateau table and" in err and "a sample log" in err
    err = _refused(capsys, "train", "--train", str(table), "--prior", str(tmp_path / "x"),
                   "--out", str(tmp_path / "m"))
    assert "--prior is for sample logs" in err


def test_a_model_with_lag_filters_is_refused_on_a_plateau_table(tmp_path: Path,
                                                                 capsys) -> None:
    from fogsf.models.samples import random_model

    table = _simulate(tmp_path / "a", 1)
    model = random_model(filters=2).save(tmp_path / "lagged")
    capsys.readouterr()
    err = _refused(capsys, "replay", str(model), str(table), "--out", str(tmp_path / "c.csv"))
    assert "lag filter(s)" in err and "plateau table holds means only" in err
