"""Search spaces for the optimizers: a box of real, integer and log-real parameters.

A parameter is ``Param(name, low, high, kind)`` with kind one of

- ``"real"``: searched as is over [low, high];
- ``"int"``: an integer in [low, high]; searched as a real coordinate over
  [low - 0.5, high + 0.5] and rounded (half up, then clipped to [low, high]) when evaluated,
  so every integer of the range owns an equal share of the box;
- ``"log-real"``: a positive real, searched as log10(value) over [log10 low, log10 high]
  (learning rates, time constants).

The optimizer moves agents in *search coordinates* (the raw value, the real-valued
integer coordinate, log10 of a log-real); `Space.decode` turns search coordinates into
values and `Space.to_params` into a ``{name: value}`` dict with ints as Python ``int``.
Bad specs are refused with `SpaceError`, which is both a `UserError` (the CLI prints it
without a traceback) and a `ValueError`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from fogsf.errors import UserError

KINDS = ("real", "int", "log-real")


class SpaceError(UserError, ValueError):
    """A search-space specification that cannot be searched; the message says why."""


@dataclass(frozen=True)
class Param:
    """One searched parameter: name, inclusive bounds and kind (real | int | log-real)."""

    name: str
    low: float
    high: float
    kind: str = "real"

    def __post_init__(self) -> None:
        where = f"search parameter {self.name!r}"
        if not isinstance(self.name, str) or not self.name:
            raise SpaceError(f"search parameter name must be a non-empty string, got "
                             f"{self.name!r}")
        if self.kind not in KINDS:
            raise SpaceError(f"{where}: unknown kind {self.kind!r}; use one of "
                             f"{', '.join(KINDS)}")
        for label, v in (("low", self.low), ("high", self.high)):
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
                raise SpaceError(f"{where}: {label} must be a number, got {v!r}")
            if not math.isfinite(float(v)):
                raise SpaceError(f"{where}: {label} must be finite, got {v!r}")
        if not float(self.low) < float(self.high):
            raise SpaceError(f"{where}: low ({self.low}) must be below high ({self.high})")
        if self.kind == "int" and (float(self.low) != int(self.low)
                                   or float(self.high) != int(self.high)):
            raise SpaceError(f"{where}: an int parameter needs integer bounds, got "
                             f"[{self.low}, {self.high}]")
        if self.kind == "log-real" and float(self.low) <= 0.0:
            raise SpaceError(f"{where}: a log-real parameter needs low > 0, got {self.low}")

    @property
    def search_bounds(self) -> tuple[float, float]:
        """Bounds of this parameter's search coordinate."""
        if self.kind == "int":
            return float(self.low) - 0.5, float(self.high) + 0.5
        if self.kind == "log-real":
            return math.log10(self.low), math.log10(self.high)
        return float(self.low), float(self.high)


def _as_param(p: Param | Mapping | Sequence) -> Param:
    if isinstance(p, Param):
        return p
    if isinstance(p, Mapping):
        unknown = set(p) - {"name", "low", "high", "kind"}
        if unknown:
            raise SpaceError(f"search parameter {p.get('name')!r}: unknown keys "
                             f"{sorted(unknown)} (expected name, low, high, kind)")
        try:
            return Param(p["name"], p["low"], p["high"], p.get("kind", "real"))
        except KeyError as e:
            raise SpaceError(f"search parameter {p.get('name')!r}: missing {e.args[0]!r}") \
                from None
    if isinstance(p, (tuple, list)) and len(p) in (3, 4):
        return Param(*p)
    raise SpaceError(f"cannot read a search parameter from {p!r}; give Param(name, low, high, "
                     "kind), a dict with those keys, or a (name, low, high[, kind]) tuple")


class Space:
    """An ordered box of `Param`s; converts between search coordinates and values."""

    def __init__(self, params: Space | Iterable[Param | Mapping | Sequence]) -> None:
        if isinstance(params, Space):
            params = params.params
        self.params: tuple[Param, ...] = tuple(_as_param(p) for p in params)
        if not self.params:
            raise SpaceError("the search space is empty: give at least one parameter")
        names = [p.name for p in self.params]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise SpaceError(f"search parameter names must be unique; repeated: {dup}")
        bounds = np.array([p.search_bounds for p in self.params], dtype=np.float64)
        self.lo: np.ndarray = bounds[:, 0]
        self.hi: np.ndarray = bounds[:, 1]
        self._is_int = np.array([p.kind == "int" for p in self.params])
        self._is_log = np.array([p.kind == "log-real" for p in self.params])
        self._int_lo = np.array([p.low for p in self.params], dtype=np.float64)
        self._int_hi = np.array([p.high for p in self.params], dtype=np.float64)

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.params]

    @property
    def dim(self) -> int:
        return len(self.params)

    def __len__(self) -> int:
        return len(self.params)

    def decode(self, z: np.ndarray) -> np.ndarray:
        """Search coordinates (..., dim) -> values as float64 (ints rounded, log-reals 10**z)."""
        z = np.asarray(z, dtype=np.float64)
        v = np.where(self._is_log, 10.0 ** np.where(self._is_log, z, 0.0), z)
        rounded = np.clip(np.floor(z + 0.5), self._int_lo, self._int_hi)
        return np.where(self._is_int, rounded, v)

    def to_params(self, z: np.ndarray) -> dict[str, int | float]:
        """One agent's search coordinates (dim,) -> {name: value}, ints as Python int."""
        v = self.decode(np.asarray(z).reshape(self.dim))
        return {p.name: int(x) if p.kind == "int" else float(x)
                for p, x in zip(self.params, v, strict=True)}

    def to_json(self) -> list[dict]:
        return [{"name": p.name, "low": p.low, "high": p.high, "kind": p.kind}
                for p in self.params]
