"""Every way a calibration block can be broken is refused with its own reason code by the C
loader (cffi, and the host driver under ASan + UBSan with the block ending exactly where its
buffer does), and by Python's read_block."""

from __future__ import annotations

import struct
from collections.abc import Callable
from pathlib import Path

import pytest

from fogsf.errors import UserError
from fogsf.export.block import (
    HEAD_BYTES,
    HEAD_FIELDS,
    STATUS,
    TABLES,
    assemble,
    block_bytes,
    block_status,
    head_values,
    model_tables,
    read_block,
    seal,
)
from fogsf.models import samples

# every optional table present: a model with the polynomial and bias heads and a play
MODEL = samples.random_model(2, 4, 1, 16, 10, seed=3, poly_head=True, bias_head=True,
                             plays=(((0.2, 0.5, 0.3), 2.0),))
GOOD = block_bytes(MODEL)


def _set(data: bytes, field: str, value: int, resealed: bool = True) -> bytes:
    out = bytearray(data)
    struct.pack_into("<I", out, 4 * HEAD_FIELDS.index(field), value)
    return bytes(seal(out) if resealed else out)


def _entry(data: bytes, slot: str, offset: int | None = None, length: int | None = None,
           resealed: bool = True) -> bytes:
    out = bytearray(data)
    at = HEAD_BYTES + 8 * TABLES.index(slot)
    off, n = struct.unpack_from("<II", out, at)
    struct.pack_into("<II", out, at, off if offset is None else offset,
                     n if length is None else length)
    return bytes(seal(out) if resealed else out)


def _entry_of(slot: str, data: bytes = GOOD) -> tuple[int, int]:
    return struct.unpack_from("<II", data, HEAD_BYTES + 8 * TABLES.index(slot))


def _flip(data: bytes, at: int) -> bytes:
    out = bytearray(data)
    out[at] ^= 0x10
    return bytes(out)


def _tables(**change: bytes) -> bytes:
    return bytes(assemble(head_values(MODEL), {**model_tables(MODEL), **change}))


def _future_slot(filled: bool) -> bytes:
    """A block of a later version's layout: one more slot, filled or not."""
    tables = {**model_tables(MODEL), **({"future_w": b"\0" * 8} if filled else {})}
    return bytes(assemble(head_values(MODEL), tables, (*TABLES, "future_w")))


def _bigger() -> bytes:
    big = samples.random_model(2, 4, 1, 32, 10, seed=3)  # H 32 > the state's 16
    return block_bytes(big)


def _weight_resealed() -> bytes:
    """A weight changed and the block's CRCs made good: the model's own CRC catches it."""
    off, _ = _entry_of("head_w")
    return bytes(seal(bytearray(_flip(GOOD, off + 1))))


RANGE = "offset out of range"
CASES: dict[str, tuple[Callable[[], bytes], str]] = {
    "truncated by a word": (lambda: GOOD[:-4], "truncated"),
    "truncated in the header": (lambda: GOOD[:60], "truncated"),
    "truncated in the directory": (lambda: GOOD[:200], "truncated"),
    "empty": (lambda: b"", "truncated"),
    "bad magic": (lambda: _flip(GOOD, 0), "bad magic"),
    "bad version": (lambda: _set(GOOD, "version", 2), "bad version"),
    "tables beyond the maximum": (lambda: _set(GOOD, "tables", 65), "bad length"),
    "header length not 112 + 8 T": (lambda: _set(GOOD, "header", 244), "bad length"),
    "total not a multiple of 4": (lambda: _set(GOOD, "total", len(GOOD) - 2), "bad length"),
    "total below the header": (lambda: _set(GOOD, "total", 100), "bad length"),
    "total past n": (lambda: _set(GOOD, "total", len(GOOD) + 4), "truncated"),
    "model format 5": (lambda: _set(GOOD, "format", 5), "model version"),
    "H over FOGSF_MAX_HIDDEN": (_bigger, "too large"),
    "K over FOGSF_MAX_FILTERS": (lambda: _set(GOOD, "k", 3), "too large"),
    "P over FOGSF_MAX_PLAYS": (lambda: _set(GOOD, "p", 2), "too large"),
    "D zero": (lambda: _set(GOOD, "d", 0), "bad sizes"),
    "N over F": (lambda: _set(GOOD, "n_in", 4 + 1), "bad sizes"),
    "quad_diag 2": (lambda: _set(GOOD, "quad_diag", 2), "bad sizes"),
    "offset past n": (lambda: _entry(GOOD, "skip_w", offset=len(GOOD) + 64), RANGE),
    "table running past the end": (lambda: _entry(GOOD, "meta", length=4096), RANGE),
    "offset inside the header": (lambda: _entry(GOOD, "feat_b", offset=64), RANGE),
    "offset 0 with a length": (lambda: _entry(GOOD, "cube_w", offset=0), RANGE),
    "misaligned offset": (lambda: _entry(GOOD, "head_w", offset=_entry_of("head_w")[0] + 2),
                          "misaligned"),
    "overlapping tables": (lambda: _entry(GOOD, "feat_b", offset=_entry_of("feat_w")[0]),
                           "overlap"),
    "table length off": (lambda: _entry(GOOD, "head_w", length=_entry_of("head_w")[1] - 4),
                         "table length"),
    "required table absent": (lambda: _entry(GOOD, "lstm_r", offset=0, length=0),
                              "table missing"),
    "cube without quad": (lambda: _entry(GOOD, "quad_w", offset=0, length=0),
                          "table missing"),
    "two of the bias head's three": (lambda: _entry(GOOD, "bias_quad_w", offset=0, length=0),
                                     "table missing"),
    "an unknown slot filled": (lambda: _future_slot(True), "unknown table"),
    "flipped byte in the header (t_min)": (lambda: _flip(GOOD, 4 * HEAD_FIELDS.index("t_min_c")),
                                           "header crc"),
    "flipped byte in the header (model crc)": (
        lambda: _flip(GOOD, 4 * HEAD_FIELDS.index("crc32") + 3), "header crc"),
    "directory's meta length changed, not resealed": (
        lambda: _entry(GOOD, "meta", length=_entry_of("meta")[1] - 4, resealed=False),
        "header crc"),
    "flipped byte in a weight": (lambda: _flip(GOOD, _entry_of("lstm_w")[0] + 101),
                                 "payload crc"),
    "flipped byte in meta": (lambda: _flip(GOOD, _entry_of("meta")[0] + 5), "payload crc"),
    "flipped padding byte": (lambda: _flip(GOOD, _entry_of("model_id")[0] + 18),
                             "payload crc"),
    "model id not hex": (lambda: _tables(model_id=MODEL.model_id.upper().encode() + b"\0"),
                         "model id"),
    "weight changed, block resealed": (_weight_resealed, "model refused"),
    "model crc changed, resealed": (lambda: _set(GOOD, "crc32", 12345), "model refused"),
}
# what Python's block_status tells apart (the rest it leaves to read_block's rebuild)
PY_STATUS = {"truncated", "bad magic", "bad version", "bad length", "model version",
             "offset out of range", "misaligned", "overlap", "unknown table", "header crc",
             "payload crc"}


# the same sizes with a rate part (R 3, Q 2): its two slots filled, format 7
RATE_MODEL = samples.random_model(2, 4, 1, 16, 10, seed=3, poly_head=True, bias_head=True,
                                  plays=(((0.2, 0.5, 0.3), 2.0),), rate_part=(3, 2),
                                  rate_fs_dps=20.0)
RATE_GOOD = block_bytes(RATE_MODEL)


def _rate_word(i: int, value: int) -> bytes:
    """Word i of the rate part's slot (R, Q, 1/FS bits) set, the block resealed."""
    out = bytearray(RATE_GOOD)
    struct.pack_into("<I", out, _entry_of("rate_head", RATE_GOOD)[0] + 4 * i, value)
    return bytes(seal(out))


def _rate_entry(slot: str, shift: int = 0, length: int | None = None) -> bytes:
    off, n = _entry_of(slot, RATE_GOOD)
    return _entry(RATE_GOOD, slot, offset=off + shift if off else 0, length=length)


RATE_CASES: dict[str, tuple[Callable[[], bytes], str]] = {
    "R above FOGSF_MAX_RATE_ROWS": (lambda: _rate_word(0, 4), "too large"),
    "R 10, past the format's bound": (lambda: _rate_word(0, 10), "too large"),
    "R zero": (lambda: _rate_word(0, 0), "bad sizes"),
    "Q zero": (lambda: _rate_word(1, 0), "bad sizes"),
    "Q 4": (lambda: _rate_word(1, 4), "bad sizes"),
    "Q 1: rate_w longer than R Q": (lambda: _rate_word(1, 1), "table length"),
    "rate_w short by a float": (lambda: _rate_entry("rate_w", length=4 * 3 * 2 - 4),
                                "table length"),
    "rate head short by a word": (lambda: _rate_entry("rate_head", length=8), "table length"),
    "rate_w misaligned": (lambda: _rate_entry("rate_w", shift=-2), "misaligned"),
    "rate head misaligned": (lambda: _rate_entry("rate_head", shift=1), "misaligned"),
    "rate_w absent": (lambda: _entry(RATE_GOOD, "rate_w", offset=0, length=0),
                      "table missing"),
    "rate_w past the end": (lambda: _rate_entry("rate_w", length=4096), RANGE),
    "format 7 without the slots": (lambda: _set(GOOD, "format", 7), "table missing"),
    "format 6 with the slots filled": (lambda: _set(RATE_GOOD, "format", 6), "table length"),
    "1/FS infinite, resealed": (lambda: _rate_word(2, 0x7F800000), "model refused"),
    "1/FS changed, resealed": (lambda: _rate_word(2, _rate_word_of(2) + 1), "model refused"),
    "rate_w weight changed, resealed": (
        lambda: bytes(seal(bytearray(_flip(RATE_GOOD, _entry_of("rate_w", RATE_GOOD)[0] + 2)))),
        "model refused"),
    "flipped byte in rate_w": (lambda: _flip(RATE_GOOD, _entry_of("rate_w", RATE_GOOD)[0] + 5),
                               "payload crc"),
}


def _rate_word_of(i: int) -> int:
    return struct.unpack_from("<I", RATE_GOOD, _entry_of("rate_head", RATE_GOOD)[0] + 4 * i)[0]


@pytest.fixture(scope="module")
def rate_kernel(tmp_path_factory: pytest.TempPathFactory):  # noqa: ANN201 - BlockKernel
    from fogsf.bindings.block import BlockKernel, build_block_lib
    return BlockKernel(RATE_MODEL, build_block_lib(RATE_MODEL,
                                                   tmp_path_factory.mktemp("ratelib")))


@pytest.mark.slow
@pytest.mark.parametrize("case", list(RATE_CASES))
def test_each_rate_part_corruption_has_its_reason(case: str, rate_kernel) -> None:  # noqa: ANN001
    make, want = RATE_CASES[case]
    data = make()
    status, bm = rate_kernel.load(data)
    assert STATUS[status] == want
    assert bm.model.format_version == 0
    if want in PY_STATUS:
        assert block_status(data) == want
    with pytest.raises(UserError):
        read_block(data)


@pytest.mark.slow
def test_a_rate_block_in_builds_with_and_without_the_part(kernel, rate_kernel) -> None:  # noqa: ANN001
    status, bm = rate_kernel.load(RATE_GOOD)
    assert STATUS[status] == "ok" and bm.model.format_version == 7
    assert (bm.model.rate_rows, bm.model.rate_coefs) == (3, 2)
    assert STATUS[rate_kernel.load(GOOD)[0]] == "ok"  # a block without it: as before
    assert STATUS[rate_kernel.load(RATE_GOOD, shift=2)[0]] == "misaligned"
    # FOGSF_MAX_RATE_ROWS 0 (the default): the kernel has no rate code and refuses the block
    assert STATUS[kernel.load(RATE_GOOD)[0]] == "too large"
    assert read_block(RATE_GOOD).model_id == RATE_MODEL.model_id


@pytest.fixture(scope="module")
def kernel(tmp_path_factory: pytest.TempPathFactory):  # noqa: ANN201 - BlockKernel
    from fogsf.bindings.block import BlockKernel, build_block_lib
    return BlockKernel(MODEL, build_block_lib(MODEL, tmp_path_factory.mktemp("blocklib")))


@pytest.mark.slow
@pytest.mark.parametrize("case", list(CASES))
def test_each_corruption_has_its_reason(case: str, kernel) -> None:  # noqa: ANN001
    make, want = CASES[case]
    data = make()
    status, bm = kernel.load(data)
    assert STATUS[status] == want
    assert bm.model.format_version == 0  # zeroed: fogsf_init refuses it
    if want in PY_STATUS:
        assert block_status(data) == want
    if case == "H over FOGSF_MAX_HIDDEN":  # a whole block of a larger model: this state's
        assert read_block(data).hidden == 32  # limit only
        return
    with pytest.raises(UserError):
        read_block(data)


@pytest.mark.slow
def test_the_good_block_and_its_edges(kernel) -> None:  # noqa: ANN001
    assert STATUS[kernel.load(GOOD)[0]] == "ok"
    assert STATUS[kernel.load(GOOD, shift=1)[0]] == "misaligned"
    assert STATUS[kernel.load(GOOD, shift=2)[0]] == "misaligned"
    assert STATUS[kernel.load(GOOD + b"\xff" * 64)[0]] == "ok"  # a flash sector's rest
    assert STATUS[kernel.load(_future_slot(False))[0]] == "ok"  # one more slot, absent
    bm = kernel.ffi.new("fogsf_block_model *")
    assert STATUS[kernel.lib.fogsf_model_from_block(kernel.ffi.NULL, 10, bm)] == "null"
    buf = kernel.ffi.from_buffer("uint8_t[]", bytearray(GOOD))
    assert STATUS[kernel.lib.fogsf_model_from_block(buf, len(GOOD), kernel.ffi.NULL)] == "null"
    assert len(set(STATUS)) == len(STATUS) == 19


@pytest.mark.slow
def test_every_corruption_under_asan(tmp_path: Path) -> None:
    """The same inputs through the host driver built with ASan + UBSan: the block in a heap
    buffer that ends with it, so a read past n is a finding."""
    import subprocess

    from fogsf.bindings.block import build_block_driver
    exe = build_block_driver(MODEL, tmp_path / "drv")
    files = []
    for i, (_, (make, _)) in enumerate(CASES.items()):
        files.append(tmp_path / f"case{i:02d}.bin")
        files[-1].write_bytes(make())
    (tmp_path / "good.bin").write_bytes(GOOD)
    for shift, good_status in ((0, "ok"), (1, "misaligned"), (3, "misaligned")):
        proc = subprocess.run([str(exe), str(shift), *map(str, files), str(tmp_path / "good.bin")],
                              capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, proc.stderr[-3000:]
        lines = proc.stdout.splitlines()
        got = [STATUS[int(line.split()[1])] for line in lines]
        want = [w for _, w in CASES.values()]
        if shift == 0:
            assert got == [*want, good_status]
            assert lines[-1].split()[2:4] == ["init", "0"]
        else:  # misaligned first, unless the header itself is short or not a block's
            assert got[-1] == good_status


@pytest.mark.slow
def test_every_rate_part_corruption_under_asan(tmp_path: Path) -> None:
    """RATE_CASES through the host driver (ASan + UBSan), its state sized for RATE_MODEL."""
    import subprocess

    from fogsf.bindings.block import build_block_driver
    exe = build_block_driver(RATE_MODEL, tmp_path / "drv")
    files = [tmp_path / f"rate{i:02d}.bin" for i in range(len(RATE_CASES))]
    for path, (make, _) in zip(files, RATE_CASES.values(), strict=True):
        path.write_bytes(make())
    (tmp_path / "good.bin").write_bytes(RATE_GOOD)
    proc = subprocess.run([str(exe), "0", *map(str, files), str(tmp_path / "good.bin")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = proc.stdout.splitlines()
    assert [STATUS[int(line.split()[1])] for line in lines] == [
        *(w for _, w in RATE_CASES.values()), "ok"]
    assert lines[-1].split()[2:4] == ["init", "0"]
