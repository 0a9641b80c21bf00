"""The calibration block (fogsf/export/block.py, firmware/c/fogsf_block.c): the same model
back in Python bit for bit, the same bytes every time, and in C the same outputs as the
generated C of the same model, bit for bit (cffi), for every shape the export writes."""

from __future__ import annotations

import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fogsf.bindings.firmware import golden_inputs
from fogsf.errors import UserError
from fogsf.export.block import TABLES, block_bytes, directory_of, head_of, read_block
from fogsf.models import samples
from fogsf.models.stream import StreamModel

FIXTURE = Path(__file__).parent / "fixtures" / "small_model"
RATE_FIXTURE = Path(__file__).parent / "fixtures" / "rate_model"


def shapes() -> dict[str, StreamModel]:
    """Every optional part of the C model, each absent and present somewhere."""
    play = (((0.2, 0.5, 0.3), 2.0),)
    return {
        "plain": samples.random_model(3, 4, 1, 16, 10, seed=1),
        "bias_diag": samples.random_model(11, 12, 1, 16, 50, seed=2, poly_head=True,
                                          lstm_inputs=1, quad_diag=True, feat_diag=True,
                                          bias_head=True),
        "play": samples.random_model(2, 4, 1, 16, 10, seed=3, poly_head=True,
                                     bias_head=True, plays=play),
        "cross": samples.random_model(3, 4, 2, 8, 10, seed=4, poly_head=True),
        "no_filters": samples.random_model(0, 2, 1, 4, 5, seed=5, taus_s=[]),
        "rate": samples.random_model(2, 4, 1, 8, 10, seed=6, poly_head=True, bias_head=True,
                                     plays=play, rate_part=(4, 3), rate_fs_dps=12.0),
    }


@pytest.mark.parametrize("name", list(shapes()))
def test_round_trip_bit_for_bit(name: str) -> None:
    model = shapes()[name]
    back = read_block(block_bytes(model))
    assert back.model_id == model.model_id
    assert back.config() == model.config()
    assert sorted(back.weights) == sorted(model.weights)
    for key, arr in model.weights.items():
        assert back.weights[key].dtype == np.float32
        assert back.weights[key].shape == arr.shape, key
        assert back.weights[key].tobytes() == arr.tobytes(), key


def test_round_trip_of_a_saved_artifact_and_a_rerated_one() -> None:
    model = StreamModel.load(FIXTURE)
    assert read_block(block_bytes(model)).model_id == model.model_id
    rate = StreamModel.load(RATE_FIXTURE)
    back = read_block(block_bytes(rate))
    assert back.model_id == rate.model_id and back.rate_fs_dps == rate.rate_fs_dps
    rated = model.at_rate(model.sample_dt_s / 2)  # `extra` gains rated_from
    assert read_block(block_bytes(rated)).config() == rated.config()


def test_same_model_same_bytes_and_the_layout() -> None:
    model = shapes()["play"]
    data = block_bytes(model)
    assert data == block_bytes(shapes()["play"])
    hd = head_of(data)
    assert data[:4] == b"FSFB" and hd["version"] == 1 and hd["total"] == len(data)
    # without the rate part the directory stops at meta: the first layout's 17 slots
    assert hd["tables"] == 17 and hd["header"] == 108 + 8 * 17 + 4
    spans = sorted((off, off + n) for off, n in directory_of(data) if off)
    assert len(spans) == 17  # the play shape fills every slot but the rate part's
    assert all(off % 4 == 0 for off, _ in spans)
    assert all(b0 >= a1 for (_, a1), (b0, _) in zip(spans, spans[1:], strict=False))
    # float32 weights as their exact bits
    off, n = directory_of(data)[TABLES.index("head_w")]
    assert data[off:off + n] == model.weights["head_w"].astype("<f4").tobytes()


def test_the_rate_part_fills_the_last_two_slots() -> None:
    model = shapes()["rate"]
    data = block_bytes(model)
    hd = head_of(data)
    assert hd["format"] == 7 and hd["tables"] == len(TABLES) == 19
    assert len([off for off, _ in directory_of(data) if off]) == 19
    off, n = directory_of(data)[TABLES.index("rate_head")]
    inv_fs = np.array([1.0 / 12.0], np.float32).view("<u4")[0]
    assert struct.unpack_from("<III", data, off) == (4, 3, inv_fs) and n == 12
    off, n = directory_of(data)[TABLES.index("rate_w")]
    assert data[off:off + n] == model.weights["rate_w"].astype("<f4").tobytes()


def test_plain_model_leaves_the_optional_slots_absent() -> None:
    data = block_bytes(shapes()["no_filters"])
    absent = {TABLES[i] for i, (off, n) in enumerate(directory_of(data)) if off == 0}
    assert absent == {"filter_alpha", "quad_w", "cube_w", "bias_w", "bias_quad_w",
                      "bias_cube_w", "play_half_c", "play_source_w"}
    assert all(n == 0 for off, n in directory_of(data) if off == 0)


def test_a_model_with_arrays_the_block_does_not_carry_is_refused() -> None:
    model = samples.random_model(2, 4, 1, 8, 10, seed=1)
    model.weights["future_w"] = np.zeros(3, np.float32)
    with pytest.raises(UserError, match="future_w.*does not carry"):
        from fogsf.export.block import model_tables
        model_tables(model)


def test_read_block_refuses_a_block_without_meta_or_with_other_tables() -> None:
    from fogsf.export.block import assemble, head_values, model_tables
    model = shapes()["plain"]
    tables = model_tables(model)
    del tables["meta"]
    with pytest.raises(UserError, match="no meta table"):
        read_block(assemble(head_values(model), tables))
    other = model_tables(shapes()["cross"])
    with pytest.raises(UserError):
        read_block(assemble(head_values(model), {**model_tables(model),
                                                  "meta": other["meta"]}))


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "fogsf", *args], capture_output=True,
                          text=True)


def test_cli_export_blob(tmp_path: Path) -> None:
    out = tmp_path / "unit.bin"
    proc = _cli("export", str(FIXTURE), "--blob", str(out))
    assert proc.returncode == 0, proc.stderr
    model = StreamModel.load(FIXTURE)
    assert out.read_bytes() == block_bytes(model)
    lines = proc.stdout.splitlines()
    assert lines[0].startswith(f"model {model.model_id} ")
    assert lines[1] == f"wrote {out} ({len(out.read_bytes())} bytes, block)"
    assert lines[2].startswith(f"block v1: {len(out.read_bytes())} bytes (header 248 B, ")
    proc = _cli("export", str(FIXTURE))
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        "fogsf export: error: nothing to write: give --out DIR (ONNX and C) and/or --blob "
        "FILE (the calibration block)"]
    helped = _cli("export", "--help").stdout.rstrip().splitlines()
    assert "--blob" in " ".join(helped)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(shapes()))
def test_block_and_generated_c_give_the_same_bits(name: str, tmp_path: Path) -> None:
    from fogsf.bindings.block import BlockKernel, build_block_lib

    model = shapes()[name]
    kernel = BlockKernel(model, build_block_lib(model, tmp_path))
    status, bm = kernel.load(block_bytes(model))
    assert status == 0
    block_model = kernel.ffi.addressof(bm, "model")
    assert kernel.ffi.string(block_model.model_id).decode() == model.model_id
    temp, gyro = golden_inputs(model, 3000)
    if model.has_rate_part:  # rates across +-2 full scales: RATE_CLAMPED beyond one
        sweep = np.linspace(-2.0, 2.0, gyro.size).astype(np.float32) * np.float32(12.0)
        gyro = np.where(np.abs(gyro) < 1e30, sweep, gyro).astype(np.float32)
    want = kernel.run(kernel.generated, temp, gyro)
    got = kernel.run(block_model, temp, gyro)
    assert want[4] == got[4] == 0  # fogsf_init accepted both
    for a, b in zip(want[:4], got[:4], strict=True):
        assert a.tobytes() == b.tobytes()
    assert np.any(got[3] & 2048) == model.has_rate_part  # RATE_CLAMPED reached
    # the model struct: the same sizes, scalars and CRCs as the generated one's
    gen = kernel.generated
    for field in ("format_version", "n_filters", "n_features", "layers", "hidden",
                  "decimation", "stuck_samples", "sample_dt_s", "t_ref_c", "t_min_c",
                  "t_max_c", "head_b", "out_scale", "out_offset", "lstm_inputs", "quad_diag",
                  "feat_diag", "crc32_sizes", "crc32", "rate_rows", "rate_coefs",
                  "rate_inv_fs"):
        assert getattr(block_model, field) == getattr(gen, field), field
    assert (block_model.rate_w == kernel.ffi.NULL) == (not model.has_rate_part)
    assert (block_model.bias == kernel.ffi.NULL) == (not model.bias_head)
    assert (block_model.plays == kernel.ffi.NULL) == (not model.n_plays)
    assert (block_model.quad_w == kernel.ffi.NULL) == (not model.poly_head)


def test_cli_export_blob_per_axis(tmp_path: Path) -> None:
    from fogsf.cli.main import main
    models = {a: samples.random_model(1, 2, 1, 4, 10, seed=i) for i, a in enumerate("xy")}
    for a, m in models.items():
        m.save(tmp_path / "models" / a)
    assert main(["export", str(tmp_path / "models"), "--axis", "all",
                 "--blob", str(tmp_path / "unit.bin")]) == 0
    for a, m in models.items():
        assert (tmp_path / f"unit_{a}.bin").read_bytes() == block_bytes(m)
