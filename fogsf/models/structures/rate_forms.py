"""The polynomial in the gyro's output and temperature that maps a plateau's mean output to
its rate: the fitted inverse of the response, so the kernel evaluates it without iterating.

A form is (P, A, Q, R): powers of x = output / full scale up to P, an |x| term when A (an SF
that differs between + and - rates), coefficients of x^0 (bias) and x^1 (SF) polynomials of
degree Q in tau = (T - t_ref) / TEMP_SCALE_C, and of |x| and x^2..x^P of degree R."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TEMP_SCALE_C = 10.0  # tau's unit: its powers stay near 1 over a rig's range
MAX_POWER = 9  # the family: powers of rate to the 9th
MAX_TEMP_DEGREE = 3  # the bias and SF heads are cubic in temperature
MAX_RATE_TEMP_DEGREE = 2


@dataclass(frozen=True)
class RateForm:
    """One candidate: `powers` P >= 1, `abs_term`, `temp_degree` Q, `rate_temp_degree` R."""

    powers: int
    abs_term: bool
    temp_degree: int
    rate_temp_degree: int

    @property
    def has_rate_part(self) -> bool:
        """True when the form holds more than a bias and a linear SF."""
        return self.powers >= 2 or self.abs_term

    @property
    def n_terms(self) -> int:
        rate_terms = max(self.powers - 1, 0) + int(self.abs_term)
        return 2 * (self.temp_degree + 1) + rate_terms * (self.rate_temp_degree + 1)

    def describe(self) -> str:
        """For people: e.g. 'x^1..x^7 + |x|, bias/SF cubic in T, rate terms linear in T'."""
        words = ("constant", "linear", "quadratic", "cubic")
        if not self.has_rate_part:
            return f"linear SF, bias and SF {words[self.temp_degree]} in T"
        odd_even = f"x^2..x^{self.powers}" if self.powers >= 2 else ""
        rate = " + ".join(t for t in (odd_even, "|x|" if self.abs_term else "") if t)
        return (f"rate terms {rate} {words[self.rate_temp_degree]} in T, bias and SF "
                f"{words[self.temp_degree]} in T")


def forms(max_power: int = MAX_POWER) -> list[RateForm]:
    """Every candidate up to `max_power`, simplest first (ties go to the simpler)."""
    out = [RateForm(p, a, q, r) for p in range(1, max_power + 1) for a in (False, True)
           for q in range(MAX_TEMP_DEGREE + 1) for r in range(MAX_RATE_TEMP_DEGREE + 1)
           if (p >= 2 or a) or r == 0]
    return sorted(out, key=lambda f: (f.n_terms, f.powers, f.abs_term, f.temp_degree,
                                      f.rate_temp_degree))


def rate_terms(x: np.ndarray, form: RateForm) -> list[np.ndarray]:
    """The rate part's terms of x, in the artifact's row order: |x| (zero when the form has
    none), then x^2 .. x^P."""
    terms = [np.abs(x) if form.abs_term else np.zeros_like(x)]
    terms += [x ** p for p in range(2, form.powers + 1)]
    return terms


def design(x: np.ndarray, tau: np.ndarray, form: RateForm) -> np.ndarray:
    """[n, form.n_terms]: x^0 tau^q and x^1 tau^q for q <= Q, then every rate term (its
    |x| column only when the form has one) times tau^r for r <= R."""
    cols = [x ** p * tau ** q for p in (0, 1) for q in range(form.temp_degree + 1)]
    terms = rate_terms(x, form)
    if not form.abs_term:
        terms = terms[1:]
    cols += [t * tau ** r for t in terms for r in range(form.rate_temp_degree + 1)]
    return np.stack(cols, axis=1)


def solve(a: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least squares with columns scaled to unit norm (the powers of x and tau differ by
    orders), so a near-singular form degrades to the minimum-norm fit, never to overflow."""
    norm = np.linalg.norm(a, axis=0)
    norm[norm == 0] = 1.0
    coef, *_ = np.linalg.lstsq(a / norm, y, rcond=None)
    return coef / norm
