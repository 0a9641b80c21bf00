"""The plateau model's form in noise (`rate_choice`): the noise the rows show prices each
term, so noisy plateaus keep fewer terms and quiet ones are chosen as before."""

from __future__ import annotations

import numpy as np

from fogsf.models.structures.rate_choice import RateRows, choose_form, noise_var
from fogsf.models.structures.rate_forms import forms


def _rows(noise: float, seed: int = 3) -> RateRows:
    """A staircase at four temperatures, y a cubic in x whose SF moves with T, plus white
    noise of `noise` (units of full scale) on every plateau."""
    steps = np.r_[0.0, np.linspace(0.2, 1.0, 5), 0.0, -np.linspace(0.2, 1.0, 5)]
    x = np.tile(np.tile(steps, 2), 4)
    tau = np.repeat(np.linspace(-1.0, 1.0, 4), 2 * steps.size)
    group = np.repeat(np.arange(4), 2 * steps.size)
    rng = np.random.default_rng(seed)
    y = 1e-4 + 2e-4 * x * tau + 3e-4 * x ** 3 + rng.normal(0.0, noise, x.size)
    return RateRows(x, tau, y, group, np.arange(x.size))


def test_the_noise_the_rows_show_is_the_noise_added() -> None:
    for noise in (1e-5, 1e-4):
        est = np.sqrt(noise_var(_rows(noise), forms()))
        assert 0.7 * noise < est < 1.3 * noise


def test_noise_keeps_fewer_terms_and_quiet_rows_keep_the_truth() -> None:
    quiet = choose_form(_rows(1e-7))
    assert quiet.form.powers >= 3 and quiet.form.temp_degree >= 1
    assert quiet.noise < 1e-6
    # in noise twice the cubic's effect the price leaves terms out, never adds them
    loud = [choose_form(_rows(6e-4, seed)) for seed in range(4)]
    assert all(c.noise > 3e-4 for c in loud)
    assert np.mean([c.form.n_terms for c in loud]) < quiet.form.n_terms


def test_the_reported_score_is_the_unpriced_heldout_rms() -> None:
    c = choose_form(_rows(1e-4))
    assert c.score == c.scores[c.form]


def test_an_odd_form_holds_odd_powers_only_and_its_artifact_corrects_as_fitted() -> None:
    from fogsf.models.structures.rate_forms import RateForm, design, rate_terms
    from fogsf.training.rate.plateau_model import PlateauRows, fit_plateau_model
    from fogsf.training.rate.plateau_train import correct_rows, rms_dph

    odd = RateForm(7, True, 1, 1, odd=True)
    assert odd.power_list == [3, 5, 7] and odd.n_terms == 2 * 2 + 4 * 2
    x, tau = np.linspace(-1.0, 1.0, 9), np.zeros(9)
    assert design(x, tau, odd).shape == (9, odd.n_terms)
    assert [float(np.abs(t).max()) for t in rate_terms(x, odd)] == [1.0, 0.0, 1.0, 0.0, 1.0,
                                                                     0.0, 1.0]
    # a sine response (odd) at four temperatures: the odd form's artifact, whose even rows
    # are zero, removes it as the full form of the same powers does
    rate = np.tile(np.r_[np.linspace(10.0, 150.0, 8), -np.linspace(10.0, 150.0, 8)], 4)
    temp = np.repeat([36.0, 43.0, 50.0, 57.0], 16)
    k = 0.3 * np.pi / 2 / 150.0 * (1.0 - 3e-4 * (temp - 45.0))
    rows = PlateauRows(np.sin(k * rate) / k * (1.0 + 2e-5 * (temp - 45.0)), rate, temp)
    for form in (RateForm(7, False, 1, 1, odd=True), RateForm(7, False, 1, 1)):
        fit = fit_plateau_model(rows, form=form)
        err = rms_dph(correct_rows(fit.model, temp, rows.gyro_dps)[0] - rate)
        assert err < 1.0, f"{form.describe()}: {err:.2f} deg/h"
