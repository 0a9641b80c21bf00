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
