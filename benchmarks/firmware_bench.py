"""Firmware benchmark: size, speed and instruction count of the C kernel per model.

For each model: parameters; Cortex-M4F flash and RAM (arm-none-eabi-size of a probe that
links kernel + model + start-up + libgcc; RAM = static data + state + the step's stack bound
from -fstack-usage); host ns per model step of the C kernel and of onnxruntime stepping the
same model; and the exact Cortex-M4F instruction count of the worst 10 Hz sample (the one that
runs a model step) from QEMU's one-instruction-per-block execution trace (deterministic),
plus the mean per sample over a decimation period.

Until trained models exist the models are seeded random weights of the trainer's sizes (the
paper's 2x200 LSTM on T and dT/dt, and the 1x16 lag-lstm on one lag-filtered temperature,
D=50); `--model NAME=DIR`
adds trained artifacts.

Images: one and three small models (1x16 LSTM with the polynomial head, seeded random weights:
one-feature models, the lag bank's shape in the default model's form, the same with a full
12 x 12 quadratic, the same with a rate part (R 8, Q 3), and the shape in the form before
lstm_inputs/quad_diag/feat_diag, for comparison) linked into one Cortex-M4F image
through the model-as-data API (`fogsf export --name`), with its flash, RAM (one state per
model, sized for the largest, + the step's stack bound) and the instructions of the worst
sample stepping every model; the target for three is <= 24 KB flash
and <= 1.5 KB RAM. Writes out/bench.json.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from fogsf.bindings.firmware import (
    CORES,
    M4F,
    Core,
    arm_size,
    arm_tools_missing,
    build_arm,
    section_sizes,
)
from fogsf.bindings.icount import sample_counts
from fogsf.bindings.kernel import EVEN_TIME, Kernel, build_kernel, state_sizes
from fogsf.bindings.stack import INIT_ROOTS, STEP_ROOTS, stack_bound
from fogsf.errors import UserError
from fogsf.export.header import write_model
from fogsf.export.onnx_step import OrtStepper, build_step_onnx
from fogsf.models import samples
from fogsf.models import stream as st
from fogsf.models.front_end import filter_alpha
from fogsf.models.structures.lag_bank import BANK_LSTM_INPUTS

TARGET = {"flash_bytes": 32 * 1024, "ram_bytes": 2 * 1024, "instructions_per_step": 50_000}
IMAGE_TARGET = {"flash_bytes": 24 * 1024, "ram_bytes": 1536}  # three small models, one image
AXES = ("imu_x", "imu_y", "imu_z")


def small_poly_models(n: int, filters: int = 1, bank_form: bool = True,
                      bias_head: bool = False, own: int = 0, play: bool = False,
                      full_quad: bool = False, rate_part: tuple[int, int] | None = None
                      ) -> list[st.StreamModel]:
    """n 1x16 LSTM models with the polynomial head (seeded random weights), one per gyro:
    one filter and feature (one effective node), or `filters` lags plus T (the lag bank's
    shape, the default model: 11 filters, 12 features). The bank's shape is the default
    model's form: the LSTM reads z[0:BANK_LSTM_INPUTS], the quadratic is diagonal and so is
    the feature map (`feat_diag`: feat_w [F]); `full_quad` keeps the rest of that form with a
    full 12 x 12 quad_w; `bank_form=False` gives the form before all three (the LSTM on all
    12, a full quad_w and feat_w); `bias_head` adds the bias head (the SF weights stay those
    drawn without it); `own` filters and features more, the bias's own (`lead` on turning
    logs: one, its coil node, whose feature mixes T and its lag, so such a model keeps the
    full feat_w); `play` a hysteresis term (one play of a mix of T and the fifth lag, and
    its feature), which the default takes when its logs turn back in temperature and ask
    for it; `rate_part` (R, Q) a rate part (the other weights stay those drawn without it)."""
    bank = filters > 1 and bank_form
    k = filters + own
    plays = (((0.5,) + (0.0,) * 4 + (0.5,) + (0.0,) * (k - 5), 6.0),) if play else ()
    return [samples.random_model(k, filters + (filters > 1) + own + play, 1, 16,
                                 decimation=50, seed=300 + a, poly_head=True,
                                 lstm_inputs=BANK_LSTM_INPUTS if bank else None,
                                 quad_diag=bank and not full_quad, bias_head=bias_head,
                                 plays=plays, feat_diag=bank and not own, rate_part=rate_part)
            for a in range(n)]


# the rate part of the image and core rows with one: R 8 terms (|x|, x^2 .. x^8), Q 3
RATE_PART = (8, 3)
RATE_LABEL = "lag-bank-1x16-rate-8x3"


# (filters, label, bank_form, bias_head, the bias's own filters, a play, a full quadratic)
# of the image rows
IMAGES = ((1, "small-lstm-1x16-poly", True, False, 0, False, False),
          (11, "lag-bank-1x16", True, False, 0, False, False),
          (11, "lag-bank-1x16-bias-head", True, True, 0, False, False),
          (11, "lag-bank-1x16-lead-bias-head", True, True, 1, False, False),
          (11, "lag-bank-1x16-play", True, False, 0, True, False),
          (11, "lag-bank-1x16-bias-head-play", True, True, 0, True, False),
          (11, "lag-bank-1x16-lead-bias-head-play", True, True, 1, True, False),
          (11, "lag-bank-1x16-full-quad-bias-head", True, True, 0, False, True),
          (11, "lag-bank-1x16-full-quad-bias-head-play", True, True, 0, True, True),
          (11, "lag-bank-1x16-all-inputs-full-quad", False, False, 0, False, False))


def write_image_models(models: list[st.StreamModel], root: Path, label: str
                       ) -> tuple[list[str], Path, Path, tuple[str, ...]]:
    """The image's models as C (one an axis) under ROOT/image{n}-{label}/models: (names,
    the image's folder, the models' folder, -D flags sizing the states for all of them)."""
    names = AXES[:len(models)]
    folder = root / f"image{len(models)}-{label}"
    gen = folder / "models"
    for name, model in zip(names, models, strict=True):
        write_model(model, gen, name)
    sizes: dict[str, int] = {}
    for model in models:
        for k, v in state_sizes(model).items():
            sizes[k] = max(sizes.get(k, 0), v)
    return names, folder, gen, tuple(f"-D{k}={v}" for k, v in sizes.items())


def bench_image(models: list[st.StreamModel], root: Path, label: str = "small-lstm-1x16-poly",
                selftest: bool = False) -> dict:
    """Flash, RAM and instructions of one Cortex-M4F image stepping all `models` (with
    `selftest`, the image calls fogsf_selftest at power-on too)."""
    names, folder, gen, defines = write_image_models(models, root, label)
    arm = build_arm(gen, None, folder / "m4f", names,
                    defines + (("-DFOGSF_BENCH_SELFTEST",) if selftest else ()))
    size = arm_size(arm, models)
    worst, mean = instructions(arm.bench_elf, models[0].decimation)
    row = {"name": f"{len(models)}x {label} in one image", "models": len(models),
           "params": sum(m.params for m in models), "flash_bytes": size.flash_bytes,
           "ram_bytes": size.ram_bytes,  # data + bss (all the states) + stack bound
           "kernel_flash_bytes": size.kernel_flash_bytes, "state_bytes": size.state_bytes,
           "stack_bytes": size.stack_bytes, "instructions_per_sample_worst": worst,
           "instructions_per_sample_mean": mean}
    row["meets_target"] = all(row[k] <= v for k, v in IMAGE_TARGET.items())
    return row


# the per-core rows: the default model's shape (the lag bank, its form), one and three, in
# the default build and in the even-time build (FOGSF_EVEN_TIME)
CORE_IMAGES = ((1, 11, False), (3, 11, False), (1, 11, True), (3, 11, True))


def bench_core(core: Core, models: list[st.StreamModel], root: Path, label: str,
               even_time: bool = False) -> dict:
    """One image on one core: flash (text + data), RAM (data + bss + the stack bound of a
    call-graph walk of the linked image, libgcc included: the deeper of fogsf_step's and the
    power-on calls'), instructions per sample (worst: a model step; mean over a period)."""
    names, folder, gen, defines = write_image_models(models, root, label)
    arm = build_arm(gen, None, folder / core.name, names,
                    defines + ((EVEN_TIME,) if even_time else ()), core=core)
    text, data, bss = section_sizes(arm.size_elf)
    step = stack_bound(arm.size_elf, STEP_ROOTS)
    init = stack_bound(arm.size_elf, INIT_ROOTS)
    c = sample_counts(arm.bench_elf, models[0].decimation, core)
    worst, mean, plain = c.worst, c.mean, c.non_step_worst
    return {"core": core.name, "image": f"{len(models)}x {label}", "models": len(models),
            "flash_bytes": text + data, "ram_bytes": data + bss + max(step.bytes, init.bytes),
            "stack_step_bytes": step.bytes, "stack_step_path": step.path,
            "stack_init_bytes": init.bytes, "stack_unbounded": step.unbounded + init.unbounded,
            "instructions_per_sample_worst": worst, "instructions_per_sample_mean": mean,
            "instructions_non_step_worst": plain, "even_time": even_time,
            "worst_over_mean": worst / mean}


def core_rows(root: Path) -> list[dict]:
    rows = []
    for core in CORES.values():
        for n, k, even in CORE_IMAGES:
            label = "lag-bank-1x16" + ("-even-time" if even else "")
            print(f"{core.name}: {n} x {label}", flush=True)
            rows.append(bench_core(core, small_poly_models(n, k), root, label, even))
    # the default shape with a rate part, on the M4F: what the part adds to a sample
    print(f"{M4F.name}: 1 x {RATE_LABEL}", flush=True)
    rows.append(bench_core(M4F, small_poly_models(1, 11, rate_part=RATE_PART), root,
                           RATE_LABEL))
    return rows


def print_core_rows(rows: list[dict]) -> None:
    print(f"\n{'core':11s} {'image':28s} {'flash B':>8s} {'RAM B':>6s} {'stack B':>7s} "
          f"{'instr/sample worst':>19s} {'mean':>7s} {'worst/mean':>10s} "
          f"{'non-step worst':>14s}  deepest chain")
    for r in rows:
        print(f"{r['core']:11s} {r['image']:28s} {r['flash_bytes']:8d} {r['ram_bytes']:6d} "
              f"{r['stack_step_bytes']:7d} {r['instructions_per_sample_worst']:19d} "
              f"{r['instructions_per_sample_mean']:7.0f} {r['worst_over_mean']:10.1f} "
              f"{r['instructions_non_step_worst']:14d}  {' > '.join(r['stack_step_path'])}")


def random_models() -> list[tuple[str, st.StreamModel, str]]:
    return [
        ("paper-lstm-2x200", samples.random_model(1, 2, 2, 200, decimation=50, seed=200),
         "random weights (seeded), the paper's 2x200 LSTM on T and dT/dt"),
        ("small-lstm-1x16", samples.random_model(1, 1, 1, 16, decimation=50, seed=16),
         "random weights (seeded), the trainer's lag-lstm size (1x16 on T_eff)"),
    ]


def host_ns_per_step(model: st.StreamModel, root: Path, steps: int) -> float:
    """C kernel: ns per model step, the same weights at D=1 so that every sample is a step
    (front end included); fogsf_run over the samples, best of 5."""
    every = replace(model, decimation=1, weights=dict(model.weights))
    every.weights["filter_alpha"] = filter_alpha(model.filter_tau_s, 1, model.sample_dt_s)
    kernel = Kernel(every, build_kernel(every, root=root))
    temp, gyro = samples.chamber_ramp(hours=steps / 36000 + 0.01, seed=1)
    temp, gyro = temp[:steps], gyro[:steps]
    best = np.inf
    for _ in range(5):
        t0 = time.perf_counter_ns()
        kernel.run(temp, gyro)
        best = min(best, (time.perf_counter_ns() - t0) / steps)
    return float(best)


def ort_ns_per_step(model: st.StreamModel, steps: int) -> float:
    """onnxruntime (1 thread): ns per session.run of the exported step, best of 3."""
    ort = OrtStepper(build_step_onnx(model), model.layers, model.hidden)
    z = np.random.default_rng(0).normal(0, 1, (steps, model.n_features)).astype(np.float32)
    best = np.inf
    for _ in range(3):
        ort.reset()
        t0 = time.perf_counter_ns()
        for m in range(steps):
            ort.step(z[m])
        best = min(best, (time.perf_counter_ns() - t0) / steps)
    return float(best)


def instructions(bench_elf: Path, decimation: int, core: Core = M4F) -> tuple[int, float]:
    """(instructions of the worst sample, mean per sample over one decimation period) of
    fogsf_step on the core, counted between the bench image's marker calls."""
    c = sample_counts(bench_elf, decimation, core)
    return c.worst, c.mean


def bench_model(name: str, model: st.StreamModel, note: str, root: Path, steps: int
                ) -> dict:
    print(f"{name}: {note}; K={model.n_filters} F={model.n_features} "
          f"{model.layers}x{model.hidden} D={model.decimation}, {model.params} params",
          flush=True)
    row: dict = {"name": name, "params": model.params, "weights": note,
                 "model_id": model.model_id, "decimation": model.decimation}
    row["host_ns_per_step"] = host_ns_per_step(model, root / "host", steps)
    row["ort_ns_per_step"] = ort_ns_per_step(model, min(steps, 3000))
    missing = arm_tools_missing()
    if missing:
        print(f"  Cortex-M4F figures skipped: {missing}")
        row.update(flash_bytes=None, ram_bytes=None, instructions_per_step=None)
        return row
    build = build_kernel(model, root=root / "host")
    arm = build_arm(build.directory, None, root / "m4f" / model.model_id,
                    defines=build.defines)
    size = arm_size(arm, model)
    worst, mean = instructions(arm.bench_elf, model.decimation)
    row.update(flash_bytes=size.flash_bytes, ram_bytes=size.ram_bytes,
               kernel_flash_bytes=size.kernel_flash_bytes, state_bytes=size.state_bytes,
               stack_bytes=size.stack_bytes, instructions_per_step=worst,
               instructions_per_sample_mean=mean)
    row["meets_target"] = all(row[k] < v for k, v in TARGET.items())
    return row


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.firmware_bench", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, default=Path("out"), help="folder for bench.json")
    p.add_argument("--model", action="append", default=[], metavar="NAME=DIR",
                   help="also bench a trained model artifact (repeatable)")
    p.add_argument("--steps", type=int, default=20000, help="host timing steps (20000)")
    p.add_argument("--build", type=Path, default=Path("build/bench"))
    p.add_argument("--cores-only", action="store_true",
                   help="only the per-core rows (Cortex-M4F, M3, M0) -> bench-cores.json")
    args = p.parse_args(argv)
    if args.cores_only:
        if arm_tools_missing():
            print(f"bench: {arm_tools_missing()}", file=sys.stderr)
            return 2
        cores = core_rows(args.build.resolve())
        print_core_rows(cores)
        args.out.mkdir(parents=True, exist_ok=True)
        path = args.out / "bench-cores.json"
        path.write_text(json.dumps({"cores": cores}, indent=2) + "\n")
        print(f"wrote {path}")
        return 0
    try:
        models = random_models()
        for spec in args.model:
            name, _, path = spec.partition("=")
            if not path:
                raise UserError(f"--model wants NAME=DIR, got {spec!r}")
            models.append((name, st.StreamModel.load(path), f"trained artifact {path}"))
        rows = [bench_model(n, m, note, args.build.resolve(), args.steps)
                for n, m, note in models]
        images = [] if arm_tools_missing() else [
            bench_image(small_poly_models(n, k, form, bias, own, play, full_quad),
                        args.build.resolve(), label)
            for k, label, form, bias, own, play, full_quad in IMAGES for n in (1, 3)]
        if images:  # the default shape with the power-on self-test linked, with a rate part
            images.append(bench_image(small_poly_models(3, 11), args.build.resolve(),
                                      "lag-bank-1x16-with-fogsf_selftest", selftest=True))
            images += [bench_image(small_poly_models(n, 11, rate_part=RATE_PART),
                                   args.build.resolve(), RATE_LABEL) for n in (1, 3)]
        cores = [] if arm_tools_missing() else core_rows(args.build.resolve())
    except UserError as e:
        print(f"bench: error: {e}", file=sys.stderr)
        return 2
    print(f"\n{'model':24s} {'params':>8s} {'flash B':>8s} {'RAM B':>7s} {'host ns':>9s} "
          f"{'ORT ns':>9s} {'M4F instr/step':>15s} {'(mean/sample)':>13s}")
    for r in rows:
        def f(v, fmt: str) -> str:  # noqa: ANN001
            return format(v, fmt) if v is not None else "-"
        print(f"{r['name']:24s} {r['params']:8d} {f(r['flash_bytes'], '8d')} "
              f"{f(r['ram_bytes'], '7d')} {r['host_ns_per_step']:9.0f} "
              f"{r['ort_ns_per_step']:9.0f} {f(r['instructions_per_step'], '15d')} "
              f"{f(r.get('instructions_per_sample_mean'), '13.0f')}")
    verdicts = ", ".join(f"{r['name']}: {'meets' if r.get('meets_target') else 'misses'}"
                         for r in rows)
    print("target (deployable): flash < 32768 B, RAM < 2048 B, < 50000 instructions per "
          f"10 Hz step; {verdicts}")
    w = max([len("image (Cortex-M4F, -O2)")] + [len(r["name"]) for r in images])
    print(f"\n{'image (Cortex-M4F, -O2)':{w}s} {'flash B':>8s} {'RAM B':>7s} "
          f"{'instr/sample worst':>19s} {'(mean)':>8s}")
    for r in images:
        print(f"{r['name']:{w}s} {r['flash_bytes']:8d} {r['ram_bytes']:7d} "
              f"{r['instructions_per_sample_worst']:19d} {r['instructions_per_sample_mean']:8.0f}")
    if images:
        threes = ", ".join(f"{r['name']}: {'meets' if r['meets_target'] else 'misses'}"
                           for r in images if r["models"] == 3)
        print(f"target (three models): flash <= {IMAGE_TARGET['flash_bytes']} B, RAM <= "
              f"{IMAGE_TARGET['ram_bytes']} B; {threes}")
    if cores:
        print_core_rows(cores)
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "bench.json"
    path.write_text(json.dumps({"models": rows, "target": TARGET, "images": images,
                                "cores": cores,
                                "image_target": IMAGE_TARGET,
                                "notes": "host_ns/ort_ns per model step (1 thread); "
                                         "instructions_per_step = Cortex-M4F instructions of "
                                         "the worst 10 Hz sample (the one running the model "
                                         "step), counted exactly under QEMU"},
                               indent=2) + "\n")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
