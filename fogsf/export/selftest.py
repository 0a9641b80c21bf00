"""Generate firmware/c/fogsf_selftest.c: the kernel's power-on self-test (`fogsf_selftest`).

A built-in 1x1 model (one lag filter, one play, the polynomial and bias heads, so every part
of the model path runs) and the activations on inputs that take every branch, with the bits
the numpy reference gives for them. `python -m fogsf.export.selftest` rewrites the file;
tests/test_kernel_guards.py checks that the committed file is what this module renders.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import fogsf
from fogsf.export.header import _context, _environment
from fogsf.models import f32, reference, samples
from fogsf.models.stream import StreamModel

NAME = "selftest_model"
SEED = 40
# every branch of exp (both clamps, both signs of the rounding) and of tanh (the clamps, the
# polynomial and the exp form on both sides), NaN, signed zero, a denormal; then inputs whose
# results an FMA-contracted build rounds otherwise (found by a sweep on x86-64 with -mfma)
ACT_X = (-100.0, -87.5, -20.25, -3.3, -0.7, -0.625, -0.3, -1e-40, -0.0, 0.0, 0.2, 0.625,
         0.63, 1.7, 9.9, 12.0, 88.5, float("nan"),
         -10.5901, -9.7932, -4.2137, -1.3723, 0.3171, 0.9137, 2.6633, 5.4719)
# a ramp with bad inputs planted: NaN and +Inf temperatures, beyond t_max and t_min, a stuck
# run longer than the threshold; NaN, infinite, beyond float32 (Inf), near its largest (the
# correction may overflow), zeros and a denormal gyro
TEMP = (15.0, 15.5, 16.25, float("nan"), 17.0, 18.5, 19.75, float("inf"), 21.0, 22.5, 80.0,
        -70.0, 24.0, 25.5, 26.0, 26.0, 26.0, 26.0, 26.0, 28.5, 30.0, 32.75, 35.0, 36.5)
GYRO = (10.0, 10.25, -5.5, 10.0, float("nan"), 3.0, 1e308, 0.0, -0.0, 12.5, 250.0, -250.0,
        10.0, 3.4e38, float("inf"), 7.0, 7.0, 7.0, 1e-40, 5.0, -3.4e38, 6.0, -float("inf"), 2.0)
PER_LINE = 6
# the float rules' probe values (fogsf_selftest.c, float_rules): a quiet NaN, -0.0, x, then
# x / 3600 (filled in by render_selftest), 1.0, 1.0e8, +Inf; x / 3600 and x * (1 / 3600)
# differ by one ulp for this x
RULE_X = 3.3000002


def selftest_model() -> StreamModel:
    """The built-in model: K=1, F=1 (of 1+K+P=3 state entries), 1x1 LSTM, D=2, stuck after 3
    samples, the polynomial and bias heads and one play."""
    return samples.random_model(1, 1, 1, 1, decimation=2, seed=SEED, stuck_samples=3,
                                poly_head=True, bias_head=True, plays=(((0.6, 0.4), 0.8),))


def _hex(values: np.ndarray, digits: int, suffix: str) -> str:
    items = [f"0x{int(v):0{digits}x}{suffix}" for v in values]
    lines = [", ".join(items[i:i + PER_LINE]) for i in range(0, len(items), PER_LINE)]
    return ",\n".join("    " + line for line in lines)


def render_selftest() -> str:
    model = selftest_model()
    ctx = _context(model, NAME) | {"embedded": True}
    env = _environment()
    model_c = env.get_template("model.c.j2").render(**ctx)
    model_c = model_c.split("*/", 2)[2]  # the model's own banner comments left out
    x = np.array(ACT_X, np.float32)
    with np.errstate(all="ignore"):
        want = np.concatenate([f32.exp_f32(x), f32.sigmoid_f32(x), f32.tanh_f32(x)])
        temp = np.array(TEMP, np.float32)
        gyro = np.array(GYRO, np.float32)
    wants = []
    for even_time in (True, False):
        out = reference.replay(model, temp, gyro, even_time=even_time)
        assert out.bias_dph is not None
        wants.append({
            "sf_want": _hex(out.sf_ppm.view(np.uint32), 8, "u"),
            "bias_want": _hex(out.bias_dph.view(np.uint32), 8, "u"),
            "corrected_want": _hex(out.corrected_dps.astype(np.float32).view(np.uint32), 8,
                                   "u"),
            "flags_want": _hex(out.flags, 2, "u")})
    x_rule = np.float32(RULE_X)
    rule = np.array([np.nan, -0.0, x_rule, x_rule / np.float32(3600.0), 1.0, 1.0e8, np.inf],
                    np.float32)
    assert rule[3] != x_rule * (np.float32(1.0) / np.float32(3600.0))  # the probe can fail
    return env.get_template("selftest.c.j2").render(
        name=NAME, model_id=model.model_id, summary=model.summary, model_c=model_c,
        n_act=len(ACT_X), n=len(TEMP),
        act_x=_hex(x.view(np.uint32), 8, "u"), act_want=_hex(want.view(np.uint32), 8, "u"),
        temp_bits=_hex(temp.view(np.uint32), 8, "u"),
        gyro_bits=_hex(gyro.view(np.uint32), 8, "u"),
        rule_bits=_hex(rule.view(np.uint32), 8, "u"), wants=wants)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m fogsf.export.selftest", description=__doc__)
    p.add_argument("--out", type=Path, default=Path(fogsf.cmake_dir) / "fogsf_selftest.c")
    args = p.parse_args(argv)
    args.out.write_text(render_selftest())
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
