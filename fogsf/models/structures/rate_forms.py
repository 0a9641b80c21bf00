"""The polynomial in the gyro's output and temperature that maps a plateau's mean output to
its rate: the fitted inverse of the response, so the kernel evaluates it without iterating.

A form is (P, A, Q, R, odd): powers of x = output / full scale up to P (the odd ones only
when `odd`), an |x| term when A (an SF that differs between + and - rates), coefficients of
x^0 (bias) and x^1 (SF) polynomials of degree Q in tau = (T - t_ref) / TEMP_SCALE_C, and of
|x| and the powers from x^2 of degree R. The odd forms are the response of a gyro whose
nonlinearity is odd (an open-loop sine, a closed-loop SF growing with |rate|): there a cubic
costs one term a degree in T, not two."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TEMP_SCALE_C = 10.0  # tau's unit: its powers stay near 1 over a rig's range
MAX_POWER = 9  # the family: powers of rate to the 9th
MAX_TEMP_DEGREE = 3  # the bias and SF heads are cubic in temperature
MAX_RATE_TEMP_DEGREE = 2


@dataclass(frozen=True)
class RateForm:
    """One candidate: `powers` P >= 1, `abs_term`, `temp_degree` Q, `rate_temp_degree` R,
    `odd`: x^3, x^5 .. x^P only (P odd, >= 3)."""

    powers: int
    abs_term: bool
    temp_degree: int
    rate_temp_degree: int
    odd: bool = False

    @property
    def power_list(self) -> list[int]:
        """The powers from x^2 the form holds."""
        return list(range(3 if self.odd else 2, self.powers + 1, 2 if self.odd else 1))

    @property
    def has_rate_part(self) -> bool:
        """True when the form holds more than a bias and a linear SF."""
        return self.powers >= 2 or self.abs_term

    @property
    def n_terms(self) -> int:
        rate_terms = len(self.power_list) + int(self.abs_term)
        return 2 * (self.temp_degree + 1) + rate_terms * (self.rate_temp_degree + 1)

    def describe(self) -> str:
        """For people: e.g. 'rate terms x^3, x^5, x^7 + |x| linear in T, bias and SF cubic in T'."""
        words = ("constant", "linear", "quadratic", "cubic")
        if not self.has_rate_part:
            return f"linear SF, bias and SF {words[self.temp_degree]} in T"
        odd_even = ("" if self.powers < 2 else f"x^2..x^{self.powers}" if not self.odd
                    else ", ".join(f"x^{p}" for p in self.power_list))
        rate = " + ".join(t for t in (odd_even, "|x|" if self.abs_term else "") if t)
        return (f"rate terms {rate} {words[self.rate_temp_degree]} in T, bias and SF "
                f"{words[self.temp_degree]} in T")


def forms(max_power: int = MAX_POWER) -> list[RateForm]:
    """Every candidate up to `max_power`, simplest first (ties go to the simpler)."""
    out = [RateForm(p, a, q, r, o) for p in range(1, max_power + 1) for a in (False, True)
           for q in range(MAX_TEMP_DEGREE + 1) for r in range(MAX_RATE_TEMP_DEGREE + 1)
           for o in (False, True)
           if ((p >= 2 or a) or r == 0) and (not o or (p >= 3 and p % 2 == 1))]
    return sorted(out, key=lambda f: (f.n_terms, f.powers, f.abs_term, f.temp_degree,
                                      f.rate_temp_degree, f.odd))


def rate_terms(x: np.ndarray, form: RateForm) -> list[np.ndarray]:
    """The rate part's terms of x, in the artifact's row order: |x|, then x^2 .. x^P (zero
    where the form holds no such term)."""
    held = set(form.power_list)
    terms = [np.abs(x) if form.abs_term else np.zeros_like(x)]
    terms += [x ** p if p in held else np.zeros_like(x) for p in range(2, form.powers + 1)]
    return terms


def design(x: np.ndarray, tau: np.ndarray, form: RateForm) -> np.ndarray:
    """[n, form.n_terms]: x^0 tau^q and x^1 tau^q for q <= Q, then every rate term the form
    holds (|x| when it has one, its powers) times tau^r for r <= R."""
    cols = [x ** p * tau ** q for p in (0, 1) for q in range(form.temp_degree + 1)]
    terms = [np.abs(x)] if form.abs_term else []
    terms += [x ** p for p in form.power_list]
    cols += [t * tau ** r for t in terms for r in range(form.rate_temp_degree + 1)]
    return np.stack(cols, axis=1)


def solve(a: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least squares with columns scaled to unit norm (the powers of x and tau differ by
    orders), so a near-singular form degrades to the minimum-norm fit, never to overflow."""
    norm = np.linalg.norm(a, axis=0)
    norm[norm == 0] = 1.0
    coef, *_ = np.linalg.lstsq(a / norm, y, rcond=None)
    return coef / norm
