"""The calibration block: one unit's model as a position-independent, little-endian, versioned
binary that firmware reads in place (firmware/c/fogsf_block.h; docs/firmware.md,
"Calibration block").

    data = block_bytes(model)        # the same model gives the same bytes
    model = read_block(data)         # the same StreamModel back, bit for bit (same model_id)

The header holds the model's sizes and scalars as fogsf_model carries them, a directory of
(offset, length) per table slot (offset 0: absent) and two CRC-32s (header, payload). The
payload holds the C model's float32 tables as their exact bits, the model id, and the
artifact's stream.json (the `meta` table, which the C loader does not read) so that Python
gets the artifact back whole: its time constants, play widths and kind are not in the C
model.
"""

from __future__ import annotations

import json
import struct
import zlib
from pathlib import Path

import numpy as np

from fogsf.errors import UserError
from fogsf.export.header import FORMAT_VERSION, FORMAT_VERSION_RATE, format_version, model_crc32
from fogsf.models.front_end import play_half_c, play_source_w
from fogsf.models.rate_part import inverse_full_scale
from fogsf.models.stream import StreamModel
from fogsf.models.stream_format import (
    _CONFIG_KEYS,
    BIAS_KEY,
    FEAT_DIAG_KEY,
    LSTM_INPUTS_KEY,
    POLY_KEY,
    QUAD_DIAG_KEY,
    RATE_ARRAY,
    RATE_KEY,
)

MAGIC = 0x42465346  # the bytes "FSFB"
BLOCK_VERSION = 1
HEAD_BYTES = 108  # the fixed header before the directory
MAX_TABLES = 64
# header words, in order (fogsf_block.h, "Layout"); FLOATS are float32 bits
HEAD_FIELDS = ("magic", "version", "total", "header", "tables", "payload_crc", "format",
               "k", "f", "l", "h", "d", "stuck", "n_in", "quad_diag", "feat_diag", "p",
               "sample_dt_s", "t_ref_c", "t_min_c", "t_max_c", "head_b", "out_scale",
               "out_offset", "bias_b", "crc32_sizes", "crc32")
FLOATS = frozenset(HEAD_FIELDS[17:25])
# table slots, in the directory's order (FOGSF_BLOCK_T_*): a new optional array is a new
# name at the end, and an older loader refuses a block that fills a slot it does not know
TABLES = ("model_id", "filter_alpha", "feat_w", "feat_b", "lstm_w", "lstm_r", "lstm_b",
          "head_w", "skip_w", "quad_w", "cube_w", "bias_w", "bias_quad_w", "bias_cube_w",
          "play_half_c", "play_source_w", "meta", "rate_head", "rate_w")
# the directory always holds the slots through meta (the first layout's 17), so a block of
# a model without a later part keeps its bytes; later slots only up to the last one filled
BASE_TABLES = TABLES.index("meta") + 1
# fogsf_block_status, by value: what the C loader returns and read_block names
STATUS = ("ok", "null", "truncated", "bad magic", "bad version", "bad length",
          "model version", "too large", "bad sizes", "misaligned", "offset out of range",
          "overlap", "table length", "table missing", "unknown table", "header crc",
          "payload crc", "model id", "model refused")
# the arrays of a StreamModel the block carries (the C model's, scalars in the header)
SCALARS = ("head_b", "out_scale", "out_offset", "bias_b")
CARRIED = frozenset({"filter_alpha", "feat_w", "feat_b", "head_w", "skip_w", "quad_w",
                     "cube_w", "bias_w", "bias_quad_w", "bias_cube_w", RATE_ARRAY, *SCALARS})


def header_length(n_tables: int) -> int:
    return HEAD_BYTES + 8 * n_tables + 4


def _f32(values: np.ndarray | list[float]) -> bytes:
    return np.asarray(values, np.float32).astype("<f4").ravel().tobytes()


def _bits(value: float | np.floating) -> int:
    return int(np.array([value], np.float32).view("<u4")[0])


def meta_json(model: StreamModel) -> bytes:
    """The artifact's stream.json, canonical (sorted keys, no spaces): the same bytes every
    time for the same model."""
    return json.dumps(model.config(), sort_keys=True, separators=(",", ":")).encode()


def model_tables(model: StreamModel) -> dict[str, bytes]:
    """Each present table's bytes by slot name (absent slots left out)."""
    unknown = sorted(set(model.weights) - CARRIED
                     - {f"lstm{i}_{g}" for i in range(model.layers) for g in "wrb"})
    if unknown:
        raise UserError(f"model {model.model_id} has array(s) {', '.join(unknown)} that "
                        f"block version {BLOCK_VERSION} does not carry: export it as C")
    w = model.weights
    layers = range(model.layers)
    tables = {"model_id": model.model_id.encode("ascii") + b"\0"}
    if model.n_filters:
        tables["filter_alpha"] = _f32(w["filter_alpha"])
    tables.update({
        "feat_w": _f32(w["feat_w"]), "feat_b": _f32(w["feat_b"]),
        "lstm_w": b"".join(_f32(w[f"lstm{i}_w"]) for i in layers),
        "lstm_r": b"".join(_f32(w[f"lstm{i}_r"]) for i in layers),
        "lstm_b": b"".join(_f32(w[f"lstm{i}_b"]) for i in layers),
        "head_w": _f32(w["head_w"]), "skip_w": _f32(w["skip_w"])})
    if model.poly_head:
        tables.update(quad_w=_f32(w["quad_w"]), cube_w=_f32(w["cube_w"]))
    if model.bias_head:
        tables.update(bias_w=_f32(w["bias_w"]), bias_quad_w=_f32(w["bias_quad_w"]),
                      bias_cube_w=_f32(w["bias_cube_w"]))
    if model.n_plays:
        tables.update(play_half_c=_f32(play_half_c(model.play_width_c)),
                      play_source_w=_f32(play_source_w(model.play_source_w,
                                                       model.n_filters)))
    tables["meta"] = meta_json(model)
    if model.has_rate_part:  # R, Q and 1/FS as the kernel holds them, then rate_w [R][Q]
        rows, coefs = w[RATE_ARRAY].shape
        tables["rate_head"] = struct.pack("<III", rows, coefs, _bits(inverse_full_scale(model)))
        tables["rate_w"] = _f32(w[RATE_ARRAY])
    return tables


def directory_slots(tables: dict[str, bytes]) -> tuple[str, ...]:
    """The slots a block of these tables declares: through meta, then through the last
    slot filled."""
    filled = [TABLES.index(name) + 1 for name in tables if name in TABLES]
    return TABLES[:max([BASE_TABLES, *filled])]


def head_values(model: StreamModel) -> dict[str, int]:
    """The header's model words (sizes, scalars as float32 bits, the model's own CRCs)."""
    w = model.weights
    crc_sizes, crc = model_crc32(model)
    words = {"format": format_version(model), "k": model.n_filters, "f": model.n_features,
             "l": model.layers, "h": model.hidden, "d": model.decimation,
             "stuck": model.stuck_samples, "n_in": model.n_lstm_inputs,
             "quad_diag": int(model.quad_diag), "feat_diag": int(model.feat_diag),
             "p": model.n_plays, "crc32_sizes": crc_sizes, "crc32": crc}
    for name in ("sample_dt_s", "t_ref_c", "t_min_c", "t_max_c"):
        words[name] = _bits(getattr(model, name))
    for name in SCALARS:
        words[name] = _bits(w[name][0]) if name in w else 0
    return words


def assemble(head: dict[str, int], tables: dict[str, bytes],
             slots: tuple[str, ...] | None = None) -> bytearray:
    """A sealed block from header words and tables by slot name: the tables in the order of
    `slots` (the directory; default directory_slots), each at a 4-aligned offset, zero
    padding, then the CRCs."""
    slots = directory_slots(tables) if slots is None else slots
    n_tables = len(slots)
    start = header_length(n_tables)
    directory = [(0, 0)] * n_tables
    payload = bytearray()
    for slot, name in enumerate(slots):
        if name in tables:
            directory[slot] = (start + len(payload), len(tables[name]))
            payload += tables[name] + b"\0" * (-len(tables[name]) % 4)
    words = {**head, "magic": MAGIC, "version": BLOCK_VERSION,
             "total": start + len(payload), "header": start, "tables": n_tables,
             "payload_crc": 0}
    data = bytearray(struct.pack(f"<{len(HEAD_FIELDS)}I", *(words[k] for k in HEAD_FIELDS)))
    for off, length in directory:
        data += struct.pack("<II", off, length)
    data += b"\0\0\0\0" + payload
    return seal(data)


def seal(data: bytearray) -> bytearray:
    """Recompute the payload CRC, then the header CRC (which covers it), in place."""
    start = _word(data, "header")
    struct.pack_into("<I", data, 20, zlib.crc32(data[start:_word(data, "total")]))
    struct.pack_into("<I", data, start - 4, zlib.crc32(data[:start - 4]))
    return data


def block_bytes(model: StreamModel) -> bytes:
    """The model's calibration block (the same model: the same bytes)."""
    model.validate()
    return bytes(assemble(head_values(model), model_tables(model)))


def write_block(model: StreamModel, path: str | Path) -> Path:
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_bytes(block_bytes(model))
    return out


def _word(data: bytes | bytearray, name: str) -> int:
    return struct.unpack_from("<I", data, 4 * HEAD_FIELDS.index(name))[0]


def head_of(data: bytes | bytearray) -> dict[str, int]:
    return dict(zip(HEAD_FIELDS, struct.unpack_from(f"<{len(HEAD_FIELDS)}I", data),
                    strict=True))


def directory_of(data: bytes | bytearray) -> list[tuple[int, int]]:
    n = _word(data, "tables")
    return [struct.unpack_from("<II", data, HEAD_BYTES + 8 * t) for t in range(n)]


def block_status(data: bytes | bytearray) -> str:
    """What the C loader checks before it reads a table, then the CRCs (the lengths each
    table must have are left to read_block, which rebuilds the model): a STATUS name."""
    n = len(data)
    if n < HEAD_BYTES + 4:
        return "truncated"
    hd = head_of(data)
    if hd["magic"] != MAGIC:
        return "bad magic"
    if hd["version"] != BLOCK_VERSION:
        return "bad version"
    if hd["tables"] > MAX_TABLES or hd["header"] != header_length(hd["tables"]):
        return "bad length"
    if hd["header"] > n:
        return "truncated"
    if hd["total"] < hd["header"] or hd["total"] % 4:
        return "bad length"
    if hd["total"] > n:
        return "truncated"
    if hd["format"] not in (FORMAT_VERSION, FORMAT_VERSION_RATE):
        return "model version"
    spans = []
    for slot, (off, length) in enumerate(directory_of(data)):
        if off == 0:
            if length:
                return "offset out of range"
            continue
        if off < hd["header"] or off + length > hd["total"]:
            return "offset out of range"
        if off % 4:
            return "misaligned"
        if slot >= len(TABLES):
            return "unknown table"
        spans.append((off, off + length))
    spans.sort()
    if any(b0 < a1 for (_, a1), (b0, _) in zip(spans, spans[1:], strict=False)):
        return "overlap"
    start = hd["header"]
    if zlib.crc32(data[:start - 4]) != struct.unpack_from("<I", data, start - 4)[0]:
        return "header crc"
    if zlib.crc32(data[start:hd["total"]]) != hd["payload_crc"]:
        return "payload crc"
    return "ok"


def _table(data: bytes | bytearray, slot: str) -> bytes | None:
    directory = directory_of(data)
    i = TABLES.index(slot)
    off, length = directory[i] if i < len(directory) else (0, 0)
    return bytes(data[off:off + length]) if off else None


def _floats(data: bytes | bytearray, slot: str, shape: tuple[int, ...]) -> np.ndarray:
    raw = _table(data, slot) or b""
    arr = np.frombuffer(raw, "<f4").astype(np.float32)
    if arr.size != int(np.prod(shape)):
        raise ValueError(f"table {slot} holds {arr.size} floats, the sizes give {shape}")
    return arr.reshape(shape)


def read_block(data: bytes | bytearray, where: str = "block") -> StreamModel:
    """The StreamModel a block holds, bit for bit (its model_id checked against the id
    table, its C tables against the header's model CRCs); a UserError naming the reason."""
    status = block_status(data)
    if status != "ok":
        raise UserError(f"{where}: not a usable calibration block: {status}")
    hd = head_of(data)
    meta = _table(data, "meta")
    if meta is None:
        raise UserError(f"{where}: the block has no meta table (stream.json): firmware can "
                        "use it, Python cannot rebuild the artifact from it")
    try:
        cfg = json.loads(meta.decode())
        model = _model(cfg, _weights(data, cfg, hd))
        model.validate(where=where)
    except (ValueError, KeyError, TypeError) as e:
        raise UserError(f"{where}: tables and meta disagree: {e}") from None
    got_id = (_table(data, "model_id") or b"").rstrip(b"\0").decode("ascii", "replace")
    if model.model_id != got_id:
        raise UserError(f"{where}: the tables and meta give model {model.model_id}, the block "
                        f"says {got_id}")
    # the header's words (what firmware runs) must be the artifact's, its CRCs included
    differ = sorted(k for k, v in head_values(model).items() if hd[k] != v)
    if _table(data, "rate_head") != model_tables(model).get("rate_head"):
        differ.append("rate_head")  # R, Q and 1/FS: the model's CRCs cover them, not meta
    if differ:
        raise UserError(f"{where}: header word(s) {', '.join(differ)} differ from model "
                        f"{got_id}'s")
    return model


def _weights(data: bytes | bytearray, cfg: dict, hd: dict[str, int]) -> dict[str, np.ndarray]:
    k, f, n_layers, h, p = (hd[x] for x in ("k", "f", "l", "h", "p"))
    n_in = hd["n_in"] or f
    w = {"filter_alpha": _floats(data, "filter_alpha", (k,)),
         "feat_w": _floats(data, "feat_w", (f,) if hd["feat_diag"] else (f, 1 + k + p)),
         "feat_b": _floats(data, "feat_b", (f,)), "head_w": _floats(data, "head_w", (h,)),
         "skip_w": _floats(data, "skip_w", (f,))}
    lw = _floats(data, "lstm_w", (4 * h * n_in + (n_layers - 1) * 4 * h * h,))
    for i, r in enumerate(_floats(data, "lstm_r", (n_layers, 4 * h, h))):
        n = n_in if i == 0 else h
        at = 0 if i == 0 else 4 * h * n_in + (i - 1) * 4 * h * h
        w[f"lstm{i}_w"] = lw[at:at + 4 * h * n].reshape(4 * h, n).copy()
        w[f"lstm{i}_r"] = r.copy()
    for i, b in enumerate(_floats(data, "lstm_b", (n_layers, 8 * h))):
        w[f"lstm{i}_b"] = b.copy()
    for name in SCALARS[:3]:
        w[name] = np.array([hd[name]], "<u4").view("<f4").astype(np.float32)
    if cfg.get(POLY_KEY, False):
        w["quad_w"] = _floats(data, "quad_w", (f,) if hd["quad_diag"] else (f, f))
        w["cube_w"] = _floats(data, "cube_w", (f,))
    if cfg.get(BIAS_KEY, False):
        w["bias_b"] = np.array([hd["bias_b"]], "<u4").view("<f4").astype(np.float32)
        for name in ("bias_w", "bias_quad_w", "bias_cube_w"):
            w[name] = _floats(data, name, (f,))
    if cfg.get(RATE_KEY):
        rate_head = _table(data, "rate_head") or b""
        if len(rate_head) != 12:
            raise ValueError(f"table rate_head holds {len(rate_head)} bytes, not 12")
        rows, coefs = struct.unpack_from("<II", rate_head)
        w[RATE_ARRAY] = _floats(data, "rate_w", (rows, coefs))
    return w


def _model(cfg: dict, weights: dict[str, np.ndarray]) -> StreamModel:
    """A StreamModel from stream.json's keys and the weights, as StreamModel.load builds it."""
    optional = (POLY_KEY, LSTM_INPUTS_KEY, QUAD_DIAG_KEY, BIAS_KEY, FEAT_DIAG_KEY, RATE_KEY)
    return StreamModel(
        model=cfg["model"], decimation=cfg["decimation"], t_ref_c=float(cfg["t_ref_c"]),
        t_min_c=float(cfg["t_min_c"]), t_max_c=float(cfg["t_max_c"]),
        stuck_samples=cfg["stuck_samples"],
        filter_tau_s=[float(t) for t in cfg["filter_tau_s"]],
        n_features=cfg["n_features"], layers=cfg["layers"], hidden=cfg["hidden"],
        weights=weights, sample_dt_s=float(cfg["sample_dt_s"]),
        extra={k: v for k, v in cfg.items() if k not in _CONFIG_KEYS and k not in optional},
        poly_head=cfg.get(POLY_KEY, False), lstm_inputs=cfg.get(LSTM_INPUTS_KEY),
        quad_diag=cfg.get(QUAD_DIAG_KEY, False), bias_head=cfg.get(BIAS_KEY, False),
        feat_diag=cfg.get(FEAT_DIAG_KEY, False), rate_fs_dps=cfg.get(RATE_KEY, 0.0))


def describe(data: bytes | bytearray) -> str:
    """One line: the block's length, header, tables present and CRCs."""
    hd = head_of(data)
    present = [TABLES[i] for i, (off, _) in enumerate(directory_of(data)) if off]
    meta = _table(data, "meta") or b""
    return (f"block v{hd['version']}: {hd['total']} bytes (header {hd['header']} B, "
            f"{len(present)} of {hd['tables']} tables, meta {len(meta)} B), header crc "
            f"0x{struct.unpack_from('<I', data, hd['header'] - 4)[0]:08x}, payload crc "
            f"0x{hd['payload_crc']:08x}")
