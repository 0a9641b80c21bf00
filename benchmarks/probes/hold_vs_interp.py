"""Between model steps: hold the output (the kernel today) or interpolate? (issue 11, 3)

The model steps once per D samples (5 s); the kernel holds its SF prediction for the next
D samples. This replays a trained model over a log with the numpy reference and scores the
log with each way of filling the samples between steps: held, linear extrapolation from the
last two steps (causal), linear interpolation one step late (causal), and interpolation to
the next step (needs the future: a bound, not an option for firmware).

    python -m benchmarks.probes.hold_vs_interp out/demo/model out/demo/run10.csv
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from fogsf.logs.logio import read_log
from fogsf.logs.measure.metrics import log_metrics
from fogsf.models import reference
from fogsf.models import stream as st


def variants(model: st.StreamModel, log) -> dict[str, np.ndarray]:  # noqa: ANN001
    """Per-sample SF predictions (ppm) of each way of filling between model steps."""
    fe = reference.frontend(log.temp_c, model.front_end)
    sf = reference.run_steps(model, fe.s).sf_ppm.astype(np.float64)
    held = reference.replay(model, log.temp_c, log.gyro_dps).sf_ppm.astype(np.float64)
    n, d, m = len(log.temp_c), model.decimation, len(sf)
    i = np.arange(n)
    k = np.minimum(i // d, m - 1)
    frac = (i - k * d) / d
    prev, cur, nxt = sf[np.maximum(k - 1, 0)], sf[k], sf[np.minimum(k + 1, m - 1)]
    return {"held (the kernel)": held,
            "linear extrapolation (causal)": cur + (cur - prev) * frac,
            "interpolation one step late (causal)": prev + (cur - prev) * frac,
            "interpolation to the next step (not causal)": cur + (nxt - cur) * frac}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("model", type=Path)
    ap.add_argument("log", type=Path)
    ap.add_argument("--json", type=Path, default=Path("out/hold-vs-interp.json"))
    args = ap.parse_args(argv)
    log = read_log(args.log)
    model = st.StreamModel.load(args.model).at_rate(log.sample_dt_s)
    rows = {}
    print(f"model {model.model_id}, D={model.decimation}; SF error after correction, "
          "100 s windows, ppm")
    for name, c in variants(model, log).items():
        met = log_metrics(log, correction_ppm=c)
        rows[name] = met
        print(f"  {name:46s} RMS {met['rms_ppm']:7.3f}  STD {met['std_ppm']:7.3f}  "
              f"max|e| {met['max_abs_ppm']:7.2f}  (floor {met['noise_floor_ppm']:.2f})")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
