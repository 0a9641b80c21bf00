"""Training loops: the streaming LSTM on windows of the model-rate sequence, and the MLP.

The LSTM learns from random windows of `window` model steps (batch `batch_size`), each
started from a zero state as the firmware starts from reset; the first `burn_in` steps of a
window are not scored. The run keeps the weights with the best validation score (RMS of the
SF residual over the SF windows of the held-out part: --window-s, --settle-s, as every
metric, `logs.measure.model_steps.step_windows`), evaluated on whole sequences from reset,
exactly as the firmware streams them.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
import torch
from tqdm import tqdm

from fogsf.logs.measure.model_steps import windows_rms
from fogsf.models.features import SeqData
from fogsf.models.nets import MLP, StreamNet
from fogsf.models.structures.lag_bank import BankFit
from fogsf.models.structures.physics_nodes import NodeFit
from fogsf.training.net.config import LSTMConfig, MLPConfig


@dataclass
class History:
    """Loss and validation curves of one training run."""

    iters: list[int] = field(default_factory=list)
    train_loss: list[float] = field(default_factory=list)
    val_rms_ppm: list[float] = field(default_factory=list)
    best_iter: int = 0
    best_val_rms_ppm: float = math.inf
    seconds: float = 0.0

    def as_dict(self) -> dict:
        return {"iters": self.iters, "train_loss": self.train_loss,
                "val_rms_ppm": self.val_rms_ppm, "best_iter": self.best_iter,
                "best_val_rms_ppm": self.best_val_rms_ppm, "seconds": self.seconds}


def windowed_rms_ppm(err_ppm: np.ndarray, windows: np.ndarray,
                     mask: np.ndarray | None = None) -> float:
    """RMS of the error averaged over each SF window (`SeqData.windows`, model-step ranges)
    of the masked steps (`logs.measure.model_steps.windows_rms`)."""
    return windows_rms(err_ppm, windows, mask)


def validation_rms(pred_ppm: list[np.ndarray], data: list[SeqData]) -> float:
    """The validation score: windowed RMS of prediction - target over the held-out steps."""
    sq, n = 0.0, 0
    for p, d in zip(pred_ppm, data, strict=True):
        if d.val_mask.any():
            r = windowed_rms_ppm(p - d.target_ppm, _windows(d), d.val_mask)
            if math.isfinite(r):
                sq += r * r
                n += 1
    return math.sqrt(sq / n) if n else math.nan


def _windows(d: SeqData) -> np.ndarray:
    """The log's SF windows; for data prepared without them, every step its own window."""
    if d.windows is not None and d.windows.size:
        return d.windows
    j = np.arange(d.n_steps)
    return np.column_stack([j, j + 1])


def predict_stream(net: StreamNet, z: np.ndarray) -> np.ndarray:
    """Normalised output over a whole sequence from reset."""
    with torch.no_grad():
        y, _ = net(torch.from_numpy(z)[None])
    return y[0].numpy().astype(np.float64)


def _poly_terms(x: np.ndarray, cubes: bool) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Columns z_i z_j (i <= j) and, with `cubes`, z_i^3, and the (i, j) of each product."""
    f = x.shape[1]
    pairs = [(i, j) for i in range(f) for j in range(i, f)]
    cols = [x[:, i] * x[:, j] for i, j in pairs]
    if cubes:
        cols += [x[:, i] ** 3 for i in range(f)]
    return np.column_stack(cols), pairs


def _init_by_least_squares(net: StreamNet, data: list[SeqData], z: list[np.ndarray],
                           out_offset: float, out_scale: float) -> None:
    """Start from the best least-squares model of the features: the skip weights and output
    bias, and with a polynomial head its quadratic (and cubic) terms too; the LSTM then
    learns only what that model leaves."""
    x = np.concatenate([a[d.train_mask] for a, d in zip(z, data, strict=True)]).astype(float)
    y = np.concatenate([(d.target_ppm[d.train_mask] - out_offset) / out_scale for d in data])
    cols = [x]
    pairs: list[tuple[int, int]] = []
    cubes = bool(net.poly and net.cube.requires_grad)
    if net.poly:
        extra, pairs = _poly_terms(x, cubes)
        cols.append(extra)
    coef, *_ = np.linalg.lstsq(np.column_stack([*cols, np.ones(len(x))]), y, rcond=None)
    f = x.shape[1]
    with torch.no_grad():
        net.skip.weight.copy_(torch.from_numpy(coef[None, :f].astype(np.float32)))
        net.head.bias.fill_(float(coef[-1]))
        net.head.weight.mul_(0.1)
        if net.poly:
            quad = np.zeros((f, f), np.float32)
            for k, (i, j) in enumerate(pairs):
                quad[i, j] = coef[f + k]
            net.quad.copy_(torch.from_numpy(quad))
            if cubes:
                net.cube.copy_(torch.from_numpy(
                    coef[f + len(pairs): f + len(pairs) + f].astype(np.float32)))


SMALL_NET_UNITS = 128  # layers x hidden at or below which one thread is fastest


@contextmanager
def torch_threads(n: int) -> Iterator[None]:
    """Run with `n` intra-op threads, then restore. Small networks are many tiny ops: on a
    busy 2-core machine, two threads make them several times slower than one."""
    before = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(before)


def _init_fixed_head(net: StreamNet, head: BankFit | NodeFit) -> None:
    """Start from a fitted lag bank or physics-node model (linear terms in the skip, squares
    on quad's diagonal, or the full quadratic of the nodes, cubes in cube, intercept in the
    head's bias) and hold it fixed: the LSTM learns only what it leaves."""
    with torch.no_grad():
        net.skip.weight.copy_(torch.from_numpy(head.lin[None, :].astype(np.float32)))
        quad = head.quad if net.quad_diag or head.quad.ndim == 2 else np.diag(head.quad)
        net.quad.copy_(torch.from_numpy(quad.astype(np.float32)))
        net.cube.copy_(torch.from_numpy(head.cube.astype(np.float32)))
        net.head.bias.fill_(float(head.intercept))
        net.head.weight.mul_(0.1)
    for p in (net.skip.weight, net.quad, net.cube):
        p.requires_grad_(False)


def train_stream(data: list[SeqData], z: list[np.ndarray], cfg: LSTMConfig,
                 out_offset: float, out_scale: float, progress: bool = True,
                 head: BankFit | NodeFit | None = None) -> tuple[StreamNet, History]:
    """Train a StreamNet on the training steps of `data` (features `z`, one per log); with
    `head`, on top of that fixed lag bank (else from the least-squares start)."""
    small = cfg.layers * cfg.hidden <= SMALL_NET_UNITS
    with torch_threads(1 if small else torch.get_num_threads()):
        return _train_stream(data, z, cfg, out_offset, out_scale, progress, head)


def _train_stream(data: list[SeqData], z: list[np.ndarray], cfg: LSTMConfig,
                  out_offset: float, out_scale: float, progress: bool,
                  head: BankFit | NodeFit | None = None) -> tuple[StreamNet, History]:
    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    net = StreamNet(z[0].shape[1], cfg.layers, cfg.hidden, poly=cfg.poly_head or head is not None,
                    cubes=cfg.cubes, lstm_inputs=cfg.lstm_inputs,
                    quad_diag=cfg.quad_diag and head is not None)
    if head is not None:
        _init_fixed_head(net, head)
    else:
        _init_by_least_squares(net, data, z, out_offset, out_scale)
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=max(cfg.iters, 1),
                                                       eta_min=cfg.lr * 0.05)
    zs = [torch.from_numpy(a) for a in z]
    ys = [torch.from_numpy(((d.target_ppm - out_offset) / out_scale).astype(np.float32))
          for d in data]
    ms = [torch.from_numpy(d.train_mask.astype(np.float32)) for d in data]
    lengths = np.array([d.n_steps for d in data])
    window = int(min(cfg.window, lengths.min()))
    weights = lengths / lengths.sum()
    hist = History()
    best_state = {k: v.clone() for k, v in net.state_dict().items()}
    has_val = any(d.val_mask.any() for d in data)
    if has_val:  # the least-squares start is a candidate too: keep it if training does worse
        hist.best_val_rms_ppm = validation_rms(
            [predict_stream(net, a) * out_scale + out_offset for a in z], data)
    t0 = time.perf_counter()
    bar = tqdm(range(1, cfg.iters + 1), desc=f"lstm {cfg.layers}x{cfg.hidden}",
               disable=not progress, leave=False, unit="it")
    for it in bar:
        which = rng.choice(len(data), size=cfg.batch_size, p=weights)
        zb, yb, mb = [], [], []
        for k in which:
            start = int(rng.integers(0, lengths[k] - window + 1))
            if rng.random() < 0.125:
                start = 0  # let it see the start from reset too
            zb.append(zs[k][start:start + window])
            yb.append(ys[k][start:start + window])
            m = ms[k][start:start + window].clone()
            if start > 0:
                m[: cfg.burn_in] = 0.0
            mb.append(m)
        out, _ = net(torch.stack(zb))
        m = torch.stack(mb)
        loss = ((out - torch.stack(yb)) ** 2 * m).sum() / m.sum().clamp(min=1.0)
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
        opt.step()
        sched.step()
        if it % cfg.eval_every == 0 or it == cfg.iters:
            hist.iters.append(it)
            hist.train_loss.append(loss.item())
            if has_val:
                preds = [predict_stream(net, a) * out_scale + out_offset for a in z]
                v = validation_rms(preds, data)
            else:
                v = float(loss)
            hist.val_rms_ppm.append(v)
            if v < hist.best_val_rms_ppm:
                hist.best_val_rms_ppm, hist.best_iter = v, it
                best_state = {k: t.clone() for k, t in net.state_dict().items()}
            bar.set_postfix(loss=f"{loss.item():.3g}", val=f"{v:.3g}")
        if cfg.time_limit_s is not None and time.perf_counter() - t0 > cfg.time_limit_s:
            break
    net.load_state_dict(best_state)
    hist.seconds = time.perf_counter() - t0
    return net, hist


def train_mlp(data: list[SeqData], z: list[np.ndarray], cfg: MLPConfig, out_offset: float,
              out_scale: float, progress: bool = True) -> tuple[MLP, History]:
    """Full-batch Adam on every training step; keeps the best validation weights."""
    small = sum(cfg.hidden) <= SMALL_NET_UNITS
    with torch_threads(1 if small else torch.get_num_threads()):
        return _train_mlp(data, z, cfg, out_offset, out_scale, progress)


def _train_mlp(data: list[SeqData], z: list[np.ndarray], cfg: MLPConfig, out_offset: float,
               out_scale: float, progress: bool) -> tuple[MLP, History]:
    torch.manual_seed(cfg.seed)
    net = MLP(z[0].shape[1], cfg.hidden)
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr)
    x = torch.from_numpy(np.concatenate([a[d.train_mask] for a, d in zip(z, data,
                                                                          strict=True)]))
    y = torch.from_numpy(np.concatenate(
        [(d.target_ppm[d.train_mask] - out_offset) / out_scale for d in data]
    ).astype(np.float32))
    hist = History()
    best_state = {k: v.clone() for k, v in net.state_dict().items()}
    has_val = any(d.val_mask.any() for d in data)
    t0 = time.perf_counter()
    for ep in tqdm(range(1, cfg.epochs + 1), desc="mlp", disable=not progress, leave=False):
        loss = ((net(x) - y) ** 2).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        if ep % cfg.eval_every == 0 or ep == cfg.epochs:
            with torch.no_grad():
                preds = [net(torch.from_numpy(a)).numpy().astype(np.float64) * out_scale
                         + out_offset for a in z]
            v = validation_rms(preds, data) if has_val else float(loss)
            hist.iters.append(ep)
            hist.train_loss.append(loss.item())
            hist.val_rms_ppm.append(v)
            if v < hist.best_val_rms_ppm:
                hist.best_val_rms_ppm, hist.best_iter = v, ep
                best_state = {k: t.clone() for k, t in net.state_dict().items()}
    net.load_state_dict(best_state)
    hist.seconds = time.perf_counter() - t0
    return net, hist
