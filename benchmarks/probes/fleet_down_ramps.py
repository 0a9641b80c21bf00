"""Probe: where a new unit's test error lies under the design's prior, and the design's play.

For each design (development designs by default: tuning belongs there), a fleet of units on
the full program of `make bench-fleet` (`benchmarks.fleet.fleet_series`), the design's prior
learned from it with several choices of its play (`design_prior.choose_play`), new units
100.. on `loop2h` and `up05`, each fitted under the prior as the bench fits it (the law
`train --prior` exports) and scored on the test loop (1 C/min up, 1.5 C/min down, 30 min
soaks): test RMS / noise floor over the whole loop, and the RMS of its 100 s windows over
the floor per segment of the chamber's program: `soak0` (the first soak), `up`, `soakhot`,
`down`, `soakend` (the soak after the down-ramp).

The prior's play, per variant:
- `now`: `choose_play` as the package runs it;
- `none`: no play;
- `nocube`: the play chosen on the law without the nodes' cubes (as now), kept whatever its
  gain;
- `cube`: the play chosen on the whole law (the nodes' cubes in), at that law's time
  constants, kept whatever its gain;
- `nocube+`, `cube+` (`--widths 2:16`): the same over other widths (the unit's own
  hysteresis term reaches 16 C);
- `best` (`--best`): the (node, width of 4, 8, 12, 16 C) whose prior scores best on the new
  units' loop2h test (an oracle: what a play can give at most).
Beside them, references that are no prior: `own`, the design's structure (with the prior's
play) fitted to the new unit's full program (what the structure leaves when the data pin
the unit), and `bayes` (`--bayes N`), the linear Bayes oracle of `fleet_bayes_oracle` (the
design's true unit prior from N noise-free units; what the short run's information allows).
The gains that would keep `nocube` and `cube` are printed per design (a design without
hysteresis sets the threshold).

    python -m benchmarks.probes.fleet_down_ramps --designs 3,4,10,15,17,19,21,22 --bayes 60
    python -m benchmarks.probes.fleet_down_ramps --designs 19,4 --best --widths 2:16
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable

import numpy as np

from benchmarks.fleet import FULL, NEW_FIRST, fleet_series, simulate_run
from benchmarks.population import HI_C, LO_C
from fogsf.logs.measure.windows import sf_windows
from fogsf.models.features import PHYSICAL_SCALE_C
from fogsf.models.structures.hysteresis import MAX_SOURCE_TAU_S, plays_batch
from fogsf.prior import design_prior as fp
from fogsf.prior.map_estimate import map_fit
from fogsf.prior.response_prior import function_fit
from fogsf.prior.unit_fit import Play, StepSeries, design_matrix, fit_taus, fit_unit, step_series
from fogsf.training.with_prior import law_prediction

RUNS = ("loop2h", "up05")
SEGMENTS = ("soak0", "up", "soakhot", "down", "soakend")
VARIANTS = ("own", "bayes", "now", "none", "nocube", "cube", "nocube+", "cube+", "best")
SOAK_S = 1800.0  # the test loop's soaks (benchmarks.population._loop(1.0, 1.5))


def segment_edges() -> list[float]:
    """The test loop's segment boundaries (s): soak, 1 C/min up, soak, 1.5 C/min down, soak."""
    up = (HI_C - LO_C) / 1.0 * 60.0
    down = (HI_C - LO_C) / 1.5 * 60.0
    t = [0.0, SOAK_S, SOAK_S + up, 2 * SOAK_S + up, 2 * SOAK_S + up + down]
    return [*t, t[-1] + SOAK_S + 1.0]


def split(test, pred: np.ndarray) -> dict[str, float]:  # noqa: ANN001 - ChamberLog
    """Whole-loop and per-segment RMS of the residual's 100 s windows over the floor."""
    w = sf_windows(test, 100.0, None, pred)
    e = (w.sf_ratio - 1.0) * 1e6
    ok = np.isfinite(w.noise_ppm)
    floor = float(np.sqrt(np.mean(w.noise_ppm[ok] ** 2)))
    t = w.t_s - float(test.time_s[0])
    edges = segment_edges()
    out = {"all": float(np.sqrt(np.mean(e**2))) / floor}
    for i, name in enumerate(SEGMENTS):
        m = (t >= edges[i]) & (t < edges[i + 1])
        out[name] = float(np.sqrt(np.mean(e[m] ** 2))) / floor if m.any() else float("nan")
        out[f"{name}_share"] = float(np.sum(e[m] ** 2) / np.sum(e**2))
    return out


def play_grid(series: list[StepSeries], taus: list[np.ndarray], k: int, node_cubes: bool,
              widths_c: tuple[float, ...] = fp.PLAY_WIDTHS_C
              ) -> tuple[Play, float, float, np.ndarray, list[int]]:
    """As `choose_play`, the law with or without the nodes' cubes: the best play, its gain on
    the whole law at `taus`, its gain on the law it was chosen against, the pooled SSE grid
    (node x width) and the nodes tried."""
    med = np.median(np.stack(taus), axis=0)
    nodes = [0] + [j + 1 for j in range(k) if med[j] <= MAX_SOURCE_TAU_S]
    widths = np.asarray(widths_c)
    sse = np.zeros((len(nodes), widths.size))
    base0 = 0.0
    for s, t in zip(series, taus, strict=True):
        x0 = design_matrix(s, t, node_cubes=node_cubes)
        base0 += fp._sse(x0, s.y)
        for a, j in enumerate(nodes):
            xs = Play(j, 0.0).source(s, t)
            h = np.vstack([plays_batch(np.repeat(x[:, None], widths.size, axis=1), widths)
                           for x in xs])[s.rows] / PHYSICAL_SCALE_C
            sse[a] += [fp._sse(np.column_stack([x0, h[:, i]]), s.y) for i in range(widths.size)]
    ia, iw = np.unravel_index(int(np.argmin(sse)), sse.shape)
    play = Play(nodes[int(ia)], float(widths[iw]))
    base = sum(fp._sse(design_matrix(s, t), s.y) for s, t in zip(series, taus, strict=True))
    with_play = sum(fp._sse(design_matrix(s, t, play), s.y)
                    for s, t in zip(series, taus, strict=True))
    return play, 1.0 - with_play / base, 1.0 - float(sse.min()) / base0, sse, nodes


def learn_with(series: dict, first: dict, chooser: Callable) -> fp.DesignPrior:
    """`design_prior.learn` with its play chosen by `chooser` (the module's own swapped in)."""
    keep = fp.choose_play
    fp.choose_play = chooser
    try:
        return fp.learn(series, first=first)
    finally:
        fp.choose_play = keep


def score_prior(prior: fp.DesignPrior, new: list[dict]) -> list[dict]:
    """Each new unit's runs fitted under `prior` (the exported law), split on its test loop."""
    rows = []
    for u in new:
        for r in RUNS:
            mf = map_fit(u[r], prior)
            law = function_fit(u[r], prior, mf.s2).law()
            pred = law_prediction(law, prior.k, u["test"], play=prior.play)
            rows.append({"unit": u["unit"], "run": r, "disagrees": bool(mf.disagrees),
                         **split(u["test"], pred)})
    return rows


def own_fit(prior: fp.DesignPrior, new: list[dict]) -> list[dict]:
    """The design's structure (with the prior's play) fitted to each new unit's full
    program, split on its test loop: what the structure leaves when the data pin the unit."""
    rows: list[dict] = []
    for u in new:
        f = fit_unit(u["full"], prior.k, np.exp(prior.mu[:prior.k]), prior.play)
        pred = law_prediction(f.theta, prior.k, u["test"], play=prior.play)
        rows.extend({"unit": u["unit"], "run": r, "disagrees": False, **split(u["test"], pred)}
                    for r in RUNS)
    return rows


def bayes_rows(design: int, new: list[dict], n_units: int) -> list[dict]:
    """The linear Bayes oracle of `fleet_bayes_oracle` (the design's TRUE unit prior, from
    `n_units` noise-free units, the noise known), split on the test loop as the prior is."""
    from benchmarks.probes.fleet_bayes_oracle import ORACLE_FIRST, _fit, clean_steps
    from fogsf.models.reference import expand
    from fogsf.training.with_prior import test_series

    units = range(ORACLE_FIRST, ORACLE_FIRST + n_units)
    test_y = np.stack([clean_steps(design, u, "loop_test") for u in units])
    mt = test_y.mean(axis=0)
    dt = (test_y - mt) / np.sqrt(n_units - 1)
    rows = []
    for r in RUNS:
        ys = np.stack([clean_steps(design, u, r) for u in units])
        ms = ys.mean(axis=0)
        ds = (ys - ms) / np.sqrt(n_units - 1)
        for u in new:
            ts, dec = test_series(u["test"], 5.0, None)
            y = _fit(ms.size, u[r].y)
            s2 = float(np.var(y - _fit(ms.size, clean_steps(design, u["unit"], r))))
            a = np.linalg.solve(ds @ ds.T / s2 + np.eye(n_units), ds @ (y - ms) / s2)
            pred = expand(_fit(ts.rows.size, mt + dt.T @ a), len(u["test"]), dec)
            rows.append({"unit": u["unit"], "run": r, "disagrees": False,
                         **split(u["test"], pred)})
    return rows


def probe_design(design: int, n_fleet: int, n_new: int, best: bool,
                 widths_c: tuple[float, ...], n_bayes: int = 0) -> dict:
    t0 = time.perf_counter()
    series = fleet_series(design, n_fleet)
    first = {k: {sn: fit_unit(s, k) for sn, s in series.items()} for k in fp.K_CHOICES}
    base = fp.learn(series, first=first)
    k = base.k
    kept = base.units[:fp.PLAY_UNITS]
    # the start `learn` gives `choose_play`: the grid fits' median time constants
    med = np.exp(np.median(np.stack([first[k][sn].theta[:k] for sn in series]), axis=0))
    ss = [series[sn] for sn in kept]
    grids = {}
    for name, cubes in (("nocube", False), ("cube", True)):
        taus = [fit_taus(s, k, med, node_cubes=cubes) for s in ss]
        grids[name] = play_grid(ss, taus, k, cubes)
        if widths_c != fp.PLAY_WIDTHS_C:
            grids[name + "+"] = play_grid(ss, taus, k, cubes, widths_c)
    new = []
    for u in range(NEW_FIRST, NEW_FIRST + n_new):
        new.append({"unit": u, "test": simulate_run(design, u, "loop_test"),
                    "full": step_series([simulate_run(design, u, r) for r in FULL]),
                    **{r: step_series([simulate_run(design, u, r)]) for r in RUNS}})
    out: dict = {"design": design, "k": k, "now_play": base.as_dict()["play"],
                 "gains": {n: {"play": [g[0].node, g[0].width_c], "whole": g[1], "own": g[2]}
                           for n, g in grids.items()},
                 "variants": {}}
    out["variants"]["now"] = score_prior(base, new)
    out["variants"]["own"] = own_fit(base, new)
    if n_bayes:
        out["variants"]["bayes"] = bayes_rows(design, new, n_bayes)
    plays: dict[str, Play | None] = {"none": None,
                                     **{n: g[0] for n, g in grids.items()}}
    for name, pl in plays.items():
        if pl == base.play:  # the same prior as now
            out["variants"][name] = out["variants"]["now"]
            continue
        prior = learn_with(series, first, lambda *a, pl=pl: pl)
        out["variants"][name] = score_prior(prior, new)
    if best:  # the oracle: every (node, width) of the grid, scored on the new units
        _, _, _, _, nodes = grids["cube"]
        trials = []
        for j in nodes:
            for wdt in (4.0, 8.0, 12.0, 16.0):
                pl = Play(j, wdt)
                prior = learn_with(series, first, lambda *a, pl=pl: pl)
                rows = score_prior(prior, new)
                loop = [r["all"] for r in rows if r["run"] == "loop2h"]
                trials.append((float(np.median(loop)) + float(np.max(loop)), j, wdt, rows))
        _, j, wdt, rows = min(trials, key=lambda x: x[0])
        out["variants"]["best"] = rows
        out["best_play"] = [j, wdt]
    out["seconds"] = time.perf_counter() - t0
    print(f"design {design}: K {k}, now {out['now_play']}; " + "; ".join(
        f"{n} {g['play']} gain {g['whole']:.4f} (own {g['own']:.4f})"
        for n, g in out["gains"].items())
        + (f"; best {out['best_play']}" if best else "") + f" ({out['seconds']:.0f} s)",
        flush=True)
    for v, rows in out["variants"].items():
        print(f"  {v:7s} " + " ".join(
            f"{r['run']} {r['all']:.2f} (up {r['up']:.2f} down {r['down']:.2f} end "
            f"{r['soakend']:.2f})" for r in rows), flush=True)
    return out


def table(results: list[dict]) -> None:
    variants = [v for v in VARIANTS if all(v in d["variants"] for d in results)]
    print("test RMS / floor, median / worst over the new units; segments: RMS of the 100 s "
          "windows in it over the floor")
    for r in RUNS:
        for v in variants:
            rows = [x for d in results for x in d["variants"][v] if x["run"] == r]
            cells = []
            for key in ("all", "up", "down", "soakend", "soakhot"):
                a = np.asarray([x[key] for x in rows])
                cells.append(f"{key} {np.median(a):.2f} / {a.max():.2f}")
            share = np.median([x["down_share"] + x["soakend_share"] for x in rows])
            print(f"  {r:6s} {v:7s} " + ", ".join(cells) + f"; down+end share {share:.2f}")


def line_options(doc: str | None) -> argparse.ArgumentParser:
    """The parser of a probe of new units on development lines: --designs, --fleet, --new,
    --bayes, --out (this probe's and `fleet_prior_steps`')."""
    ap = argparse.ArgumentParser(description=doc,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--designs", default="3,4,10,15,17,19,21,22")
    ap.add_argument("--fleet", type=int, default=20, help="units on the full program")
    ap.add_argument("--new", type=int, default=3, help="new units per design")
    ap.add_argument("--bayes", type=int, default=0,
                    help="the linear Bayes oracle from this many noise-free units (0: none)")
    ap.add_argument("--out", default=None, help="JSON of every row")
    return ap


def report(args: argparse.Namespace, results: list[dict], table: Callable[[], None]
           ) -> int:
    """The probe's table printed under its line, its rows written to --out."""
    print(f"designs {args.designs}, fleet of {args.fleet}, {args.new} new units each")
    table()
    if args.out:
        with open(args.out, "w") as fh:
            json.dump(results, fh, indent=1)
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = line_options(__doc__)
    ap.add_argument("--best", action="store_true", help="the oracle play per design too")
    ap.add_argument("--widths", default=None,
                    help="play widths (C) of the `+` variants, e.g. 2:16 (default: none)")
    args = ap.parse_args(argv)
    widths = fp.PLAY_WIDTHS_C
    if args.widths:
        lo, hi = (int(x) for x in args.widths.split(":"))
        widths = tuple(float(w) for w in range(lo, hi + 1))
    results = [probe_design(int(d), args.fleet, args.new, args.best, widths, args.bayes)
               for d in args.designs.split(",")]
    return report(args, results, lambda: table(results))


if __name__ == "__main__":
    raise SystemExit(main())
