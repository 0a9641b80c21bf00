"""fogsf simulate: a closed-loop FOG on a rate table in a temperature chamber, at 10 Hz
(or at --sample-rate-hz, 1 Hz .. 4 kHz).

Writes a chamber log (the CSV of docs/logs.md) with the board thermometer (temp_c), the
table rate, the gyro output, the earth rate, the chamber air (chamber_c), every internal
node's thermometer (temp_<node>_c) and the truth (true_sf_ppm: the SF error vs nominal per
sample; true_bias_dph). The physics (fogsf.sim): a thermal network of first-order lags
(housing, board, preamp, coil inner/outer, source, each with self-heating), the SF from
K = 2*pi*L*D/(Km*K_DA*lambda*c) with each factor's temperature law, bias(T), angle random
walk, output pulse quantization and DS18B20-like thermometers. The same seed gives the same
bytes.

Start from a scenario (--scenario, default paper) or a full configuration (--config
sim.json, e.g. from --write-config or from fogsf diagnose); the options below override it.
--plateaus writes the run as a rig's DAQ does: one row per rate plateau (means only), at set
points --levels-c (36,43,50,57 C), with fogsf-columns.toml (layout = "plateaus") beside it.

examples:
  fogsf simulate --scenario paper --ramp-rate 1.0 --seed 7 --out run10.csv --summary
  fogsf simulate --scenario paper --ramp-rate 0.5 --effect temp_rate=30 --out run05.csv
  fogsf simulate --random-gyro 17 --ramp-rate 1.0 --summary
  fogsf simulate --scenario paper --ramp-rate 1.0 --sample-rate-hz 100 --out run10_100hz.csv
  fogsf simulate --profile cycle --start-c -20 --stop-c 60 --table alternating --out c.csv
  fogsf simulate --program chamber.csv --table levels --rates-dps 10,100,-10,-100 --out p.csv
  fogsf simulate --scenario paper --plot sim_paper.png
  fogsf simulate --list-effects
  fogsf simulate --rig ros --protocol staircase --random-gyro 17 --out rig/ros.csv
  fogsf simulate --rig imu3 --protocol reversals --gyro-seeds 1,2,3 --out imu/imu.csv
  fogsf simulate --plateaus --random-gyro 17 --effect open_loop=0.2 --out plat/table.csv
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
from typing import Any

from fogsf.cli.inspect import summary as log_summary
from fogsf.errors import UserError
from fogsf.logs.chamber_log import check_rate_hz
from fogsf.logs.writer import write_log
from fogsf.sim import profiles
from fogsf.sim.config import SimConfig, validate
from fogsf.sim.effects import describe, parse_effect
from fogsf.sim.gyro import SimResult, simulate
from fogsf.sim.plot import plot_runs, runs_for_plot
from fogsf.sim.population import gyro_for_seed, with_gyro
from fogsf.sim.rigs import plateau_tables as plateaus
from fogsf.sim.rigs import protocols as rigs
from fogsf.sim.rigs import rig_logs
from fogsf.sim.scenarios import SCENARIOS, scenario


def _floats(text: str) -> list[float]:
    try:
        return [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers like 10,50, got {text!r}") from None


def _ints(text: str) -> list[int]:
    try:
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected whole numbers like 1,2,3, got {text!r}"
                                         ) from None


def configure(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("what to run")
    src = g.add_mutually_exclusive_group()
    src.add_argument("--scenario", choices=sorted(SCENARIOS), default=None,
                     help="a named run of the default gyro (default: paper)")
    src.add_argument("--config", metavar="SIM.JSON",
                     help="a full simulator configuration (JSON, as --write-config writes)")
    g.add_argument("--ramp-rate", type=float, metavar="C_PER_MIN",
                   help="chamber ramp rate in C/min (paper: 0.5 and 1.0)")
    g.add_argument("--seed", type=int, help="random seed (same seed, same bytes)")
    g.add_argument("--random-gyro", type=int, metavar="GYRO_SEED",
                   help="a gyro drawn from the population (docs/population.md; "
                        "0 is the default gyro) instead of the default gyro; the run's noise "
                        "seed is GYRO_SEED unless --seed is given. Seeds 0-9999 are the "
                        "development range, 20000-29999 the evaluation range")
    g.add_argument("--thermal-bias", action="store_true",
                   help="with --random-gyro: the gyro's thermal bias as the population draws "
                        "it for make bench-bias (on its coil: a Shupe term, a quadratic and a "
                        "cubic; docs/simulate.md); its offset and slope only without it")
    g.add_argument("--effect", action="append", default=[], metavar="NAME=STRENGTH[,k=v]",
                   help="switch on an effect (repeatable); see --list-effects")

    p = parser.add_argument_group("chamber program")
    p.add_argument("--profile", choices=["soak", "ramp", "cycle", "steps", "program"],
                   help="kind of chamber program (the scenario's otherwise; paper: ramp)")
    p.add_argument("--start-c", type=float, help="first (or soak) temperature, C")
    p.add_argument("--stop-c", type=float, help="ramp / cycle end temperature, C")
    p.add_argument("--soak-before-min", type=float, help="soak before a ramp / cycle, min")
    p.add_argument("--soak-after-min", type=float, help="soak after a ramp, min")
    p.add_argument("--soak-min", type=float, help="soak at each cycle end / step, min")
    p.add_argument("--duration-min", type=float,
                   help="run length, min: a soak's length; any other program is cut there "
                        "or held at its last temperature until then")
    p.add_argument("--cycles", type=int, help="number of up-down cycles")
    p.add_argument("--levels-c", type=_floats, metavar="T1,T2,...", help="step temperatures")
    p.add_argument("--program", metavar="CHAMBER.CSV",
                   help="chamber program as CSV rows time_s,temp_c (linear in between)")
    p.add_argument("--start", choices=["warm", "power-on"],
                   help="warm: at equilibrium at t=0 (paper); power-on: switched on at t=0")

    t = parser.add_argument_group("rate table")
    t.add_argument("--table", choices=["constant", "alternating", "levels"],
                   help="schedule kind: constant rate, alternating +/-, or rate levels")
    t.add_argument("--rate-dps", type=float, help="table rate, deg/s (constant / alternating)")
    t.add_argument("--rates-dps", type=_floats, metavar="R1,R2,...", help="rate levels, deg/s")
    t.add_argument("--dwell-s", type=float, help="time on each rate (alternating / levels), s")

    n = parser.add_argument_group("site and noise")
    n.add_argument("--sample-rate-hz", type=float, metavar="HZ",
                   help="samples per second, 1 .. 4000 (default 10)")
    n.add_argument("--latitude-deg", type=float,
                   help="latitude for the earth rate; the simulated gyro's sensitive axis "
                        "is vertical (earth_rate_dps = EARTH_RATE * sin(latitude))")
    n.add_argument("--arw", type=float, metavar="DEG_PER_SQRT_H",
                   help="angle random walk (default 0.05 deg/sqrt(h))")
    n.add_argument("--pulse-arcsec", type=float, help="output pulse weight (0: no quantization)")
    n.add_argument("--temp-noise-c", type=float, help="thermometer noise, 1 sigma, C")
    n.add_argument("--no-noise", action="store_true",
                   help="no gyro noise, no quantization, ideal thermometers")

    r = parser.add_argument_group(
        "calibration rig (docs/simulate.md, 'Rig protocols'): a protocol written the way a "
        "rig writes its log, with the column map (fogsf-columns.toml) beside it")
    r.add_argument("--rig", choices=["ros", "plain", "imu3"],
                   help="ros: sec,nanosec,gyro_raw (rad/s),...,rig_rate (steps/s), flags; "
                        "plain: epoch time_s, gyro in rad/s; imu3: three skew-mounted gyros")
    r.add_argument("--protocol", choices=["reversals", "staircase", "stationary"],
                   default="reversals",
                   help="reversals: +/- --rate-dps (100) every --dwell-s (60) over a 1 C/min "
                        "ramp; staircase: 0, 4 ... --rate-dps (100) deg/s both ways, "
                        "--dwell-s (16) a step, at 5 bang-bang set points; stationary: the "
                        "table stopped through a -20 -> 50 -> -20 C loop (the bias alone)")
    r.add_argument("--gyro-seeds", type=_ints, metavar="A,B,C",
                   help="the population's gyros for --rig imu3 (default: --random-gyro "
                        "and the next two)")
    r.add_argument("--accel-dps2", type=float, help="table acceleration (default 300)")
    r.add_argument("--stalls-per-h", type=float, help="table stalls an hour (default 0)")
    r.add_argument("--stamp-jitter-s", type=float,
                   help="time stamps off the sample times by up to this, s (default 0; at "
                        "most 5 %% of a sample)")
    r.add_argument("--temp-lsb-c", type=float,
                   help="thermometer step, C (1, 0.25, default 0.0625)")
    r.add_argument("--truth", metavar="TRUTH.CSV",
                   help="also write the truth per sample (one file per axis for imu3)")

    q = parser.add_argument_group(
        "plateau table (docs/simulate.md, 'Plateau tables'): at each set point --levels-c, "
        "after --soak-min (20) with the table stopped, --passes staircases 0, +dw ... +max, "
        "0, -dw ... -max; one row per plateau (time_s its start, duration_s, table_rate_dps, "
        "gyro_dps and temp_c the means over it after 2 s)")
    q.add_argument("--plateaus", action="store_true", help="write the run as a plateau table")
    q.add_argument("--plateau-s", type=float, help="a plateau's length, s (default 18)")
    q.add_argument("--max-rate", type=float, metavar="DPS", help="top rate (default 150)")
    q.add_argument("--rate-steps", type=int, help="steps from 0 to the top (default 5)")
    q.add_argument("--passes", type=int, help="staircases at each set point (default 2)")

    o = parser.add_argument_group("output")
    o.add_argument("--out", metavar="LOG.CSV", help="write the chamber log here (Parquet when "
                   "it ends in .parquet)")
    o.add_argument("--summary", action="store_true",
                   help="print the log's summary and SF-error metrics block")
    o.add_argument("--window-s", type=float, default=100.0, help="SF window for --summary/--plot")
    o.add_argument("--plot", metavar="FILE.PNG",
                   help="temperatures (paper Fig. 3) and SF error vs board temperature at "
                        "0.5 and 1 C/min for a ramp (paper Fig. 7)")
    o.add_argument("--write-config", metavar="SIM.JSON",
                   help="write the effective configuration ('-' for stdout)")
    o.add_argument("--list-effects", action="store_true", help="list the effects and exit")


def build_config(args: argparse.Namespace) -> SimConfig:
    if args.config:
        cfg = SimConfig.load(args.config)
    else:
        cfg = scenario(args.scenario or "paper")
    cfg = copy.deepcopy(cfg)
    if args.random_gyro is not None:
        if args.random_gyro < 0:
            raise UserError(f"--random-gyro must be >= 0, got {args.random_gyro}")
        cfg = with_gyro(cfg, gyro_for_seed(args.random_gyro,
                                           thermal_bias=args.thermal_bias))
        cfg.seed = args.random_gyro
    elif args.thermal_bias:
        raise UserError("--thermal-bias is the population's: give --random-gyro SEED too")
    if args.seed is not None:
        cfg.seed = args.seed
    pr = cfg.profile
    if args.profile:
        pr.kind = args.profile
    if args.program:
        pr.kind = "program"
        pr.points = profiles.read_program(args.program)
    for opt, attr, scale in (("ramp_rate", "rate_c_per_min", 1.0), ("start_c", "start_c", 1.0),
                             ("stop_c", "stop_c", 1.0), ("soak_before_min", "soak_before_s", 60),
                             ("soak_after_min", "soak_after_s", 60), ("soak_min", "soak_s", 60),
                             ("cycles", "cycles", 1), ("levels_c", "levels_c", 1)):
        v = getattr(args, opt)
        if v is not None:
            setattr(pr, attr, v * scale if scale != 1 else v)
    if args.duration_min is not None:
        if args.duration_min <= 0:
            raise UserError("--duration-min must be > 0")
        if pr.kind == "soak":
            pr.duration_s = args.duration_min * 60.0
        else:
            pr.total_s = args.duration_min * 60.0
    if args.start:
        cfg.thermal.start = args.start
    tb = cfg.table
    if args.table:
        tb.kind = args.table
    if args.rate_dps is not None:
        tb.rate_dps = args.rate_dps
    if args.rates_dps is not None:
        tb.rates_dps = args.rates_dps
        if not args.table:
            tb.kind = "levels"
    if args.dwell_s is not None:
        tb.dwell_s = args.dwell_s
    if args.latitude_deg is not None:
        cfg.latitude_deg = args.latitude_deg
    if args.sample_rate_hz is not None:
        cfg.dt_s = 1.0 / check_rate_hz(args.sample_rate_hz)
    nz = cfg.noise
    if args.no_noise:
        nz.arw_deg_per_sqrt_h = nz.pulse_arcsec = nz.temp_noise_c = nz.temp_lsb_c = 0.0
    if args.arw is not None:
        nz.arw_deg_per_sqrt_h = args.arw
    if args.pulse_arcsec is not None:
        nz.pulse_arcsec = args.pulse_arcsec
    if args.temp_noise_c is not None:
        nz.temp_noise_c = args.temp_noise_c
    for text in args.effect:
        e = parse_effect(text)
        cfg.effects = [x for x in cfg.effects if x.name != e.name] + [e]
    validate(cfg)
    return cfg


def summary(result: SimResult, window_s: float) -> dict[str, Any]:
    """`fogsf inspect --json`'s summary of the log, plus the truth behind it."""
    try:
        out = log_summary(result.log, window_s, None, None)
    except UserError as e:  # e.g. the board never passes 20 C: no reference SF
        out = {"samples": len(result.log), "duration_s": result.log.duration_s,
               "metrics": None,
               "metrics_note": str(e).replace("give it with --ref-sf", "read the written log "
                                              "with `fogsf inspect LOG --ref-sf`")}
    out["true_sf_ppm_range"] = [float(result.sf_ppm.min()), float(result.sf_ppm.max())]
    return out


def run(args: argparse.Namespace) -> int:
    if args.list_effects:
        print(describe())
        return 0
    if args.rig:
        return run_rig(args)
    if args.plateaus or any(getattr(args, o) is not None for o in PLATEAU_OPTIONS):
        return run_plateaus(args)
    if not (args.out or args.summary or args.plot or args.write_config):
        raise UserError("nothing to do: give --out LOG.CSV, --summary, --plot FILE.png or "
                        "--write-config SIM.JSON")
    cfg = build_config(args)
    if args.write_config:
        if args.write_config == "-":
            sys.stdout.write(cfg.to_json())
        else:
            cfg.save(args.write_config)
            print(f"configuration -> {args.write_config}", file=sys.stderr)
    if not (args.out or args.summary or args.plot):
        return 0
    result = simulate(cfg)
    if args.out:
        write_log(args.out, result.log)
        print(f"{len(result.log)} samples ({result.log.duration_s / 3600:.2f} h) -> {args.out}",
              file=sys.stderr)
    if args.summary:
        print(json.dumps(summary(result, args.window_s), indent=2))
    if args.plot:
        plot_runs(runs_for_plot(cfg, result), args.plot, args.window_s)
        print(f"figure -> {args.plot}", file=sys.stderr)
    return 0


# options of the chamber-program and table groups that a rig protocol replaces
RIG_REFUSES = ("scenario", "config", "ramp_rate", "profile", "start_c", "stop_c",
               "soak_before_min", "soak_after_min", "soak_min", "duration_min", "cycles",
               "levels_c", "program", "start", "table", "rates_dps", "pulse_arcsec",
               "temp_noise_c", "plot", "write_config", "summary", "plateaus")


def _rig_protocol(args: argparse.Namespace) -> Any:
    kw: dict[str, Any] = {"effects": [parse_effect(text) for text in args.effect]}
    if args.sample_rate_hz is not None:
        kw["rate_hz"] = check_rate_hz(args.sample_rate_hz)
    for opt, key in (("accel_dps2", "accel_dps2"), ("stalls_per_h", "stalls_per_h"),
                     ("temp_lsb_c", "temp_lsb_c"), ("latitude_deg", "latitude_deg"),
                     ("stamp_jitter_s", "stamp_jitter_s"),
                     ("arw", "arw_deg_per_sqrt_h")):
        v = getattr(args, opt)
        if v is not None:
            if v < 0 or (opt == "latitude_deg" and abs(v) > 90):
                raise UserError(f"--{opt.replace('_', '-')} {v:g}: out of range")
            kw[key] = v
    for opt in ("rate_dps", "dwell_s"):
        v = getattr(args, opt)
        if v is not None and v <= 0:
            raise UserError(f"--{opt.replace('_', '-')} must be > 0, got {v:g}")
    if args.protocol == "reversals":
        return rigs.reversal_protocol(args.rate_dps or 100.0, args.dwell_s or 60.0, **kw)
    if args.protocol == "stationary":
        if args.rate_dps is not None or args.dwell_s is not None:
            raise UserError("--protocol stationary keeps the table stopped: --rate-dps and "
                            "--dwell-s do not apply")
        return rigs.stationary_protocol(**kw)
    step = 4.0
    top = args.rate_dps or 100.0
    if top < step:
        raise UserError(f"--rate-dps {top:g}: the staircase goes up in {step:g} deg/s steps")
    return rigs.staircase_protocol(step, top, args.dwell_s or 16.0, **kw)


def run_rig(args: argparse.Namespace) -> int:
    """--rig: a calibration rig's protocol written in its convention (sim/rigs/protocols.py)."""
    from pathlib import Path

    given = [f"--{o.replace('_', '-')}" for o in RIG_REFUSES if getattr(args, o, None)]
    if given:
        raise UserError(f"--rig runs its own protocol: {', '.join(given)} does not apply "
                        "(see --protocol)")
    if not args.out:
        raise UserError("--rig needs --out LOG.CSV (the column map is written beside it)")
    base = args.random_gyro if args.random_gyro is not None else 0
    seeds = args.gyro_seeds or ([base, base + 1, base + 2] if args.rig == "imu3" else [base])
    if any(s < 0 for s in seeds):
        raise UserError(f"gyro seeds must be >= 0, got {seeds}")
    want = 3 if args.rig == "imu3" else 1
    if len(seeds) != want:
        raise UserError(f"--rig {args.rig} takes {want} gyro seed(s), got {len(seeds)}")
    seed = args.seed if args.seed is not None else seeds[0]
    protocol = _rig_protocol(args)
    if args.thermal_bias:
        from dataclasses import replace

        if len(seeds) != 1:
            raise UserError("--thermal-bias takes one gyro: not with --rig imu3")
        protocol = replace(protocol, bias=gyro_for_seed(seeds[0], thermal_bias=True).bias)
    log = rig_logs.rig_log(args.rig, args.out, protocol, seeds, seed)
    rows = len(next(iter(log.truth.values())).time_s)
    print(f"{rows} samples -> {log.path}"
          + (f", column map -> {log.mapping_path}" if log.mapping_path else ""),
          file=sys.stderr)
    if args.truth:
        for axis, truth in log.truth.items():
            p = Path(args.truth)
            out = p.with_name(f"{p.stem}_{axis}{p.suffix}") if axis else p
            rig_logs.write_truth(out, truth)
            print(f"truth -> {out}", file=sys.stderr)
    return 0


# options of the chamber-program and table groups that the plateau program replaces
PLATEAU_REFUSES = ("profile", "start_c", "stop_c", "soak_before_min", "soak_after_min",
                   "duration_min", "cycles", "program", "start", "table", "rate_dps",
                   "rates_dps", "dwell_s", "plot", "summary", "write_config")


PLATEAU_OPTIONS = ("plateau_s", "max_rate", "rate_steps", "passes")


def run_plateaus(args: argparse.Namespace) -> int:
    """--plateaus: the gyro of build_config through a rig's set points, as a plateau table."""
    if not args.plateaus:
        raise UserError("--plateau-s, --max-rate, --rate-steps and --passes need --plateaus")
    given = [f"--{o.replace('_', '-')}" for o in PLATEAU_REFUSES if getattr(args, o, None)]
    if given or not args.out:
        raise UserError(f"--plateaus runs its own program: {', '.join(given)} does not apply"
                        if given else "--plateaus needs --out TABLE.CSV (and writes its map)")
    plan = plateaus.plan_from(plateau_s=args.plateau_s, max_rate_dps=args.max_rate,
                              rate_steps=args.rate_steps, passes=args.passes,
                              ramp_c_per_min=args.ramp_rate, set_points_c=args.levels_c,
                              soak_s=None if args.soak_min is None else args.soak_min * 60.0)
    args.ramp_rate = args.levels_c = args.soak_min = None  # the plan's, not a profile's
    table = plateaus.plateau_table(plateaus.run_plateaus(build_config(args), plan))
    out, toml = plateaus.write_plateau_table(args.out, table)
    print(f"{len(table)} plateaus -> {out}, column map -> {toml}", file=sys.stderr)
    if args.truth:
        print(f"truth -> {plateaus.write_plateau_truth(args.truth, table)}", file=sys.stderr)
    return 0
