"""The trainer's network (torch), written as an artifact by the trainer's own converter, gives
the same SF prediction in the C kernel: trainer -> artifact -> firmware end to end."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from kernel_helpers import kernel_for

from fogsf.bindings.kernel import trace_steps
from fogsf.models import reference, samples
from fogsf.models.front_end import FrontEnd, filter_alpha

features = pytest.importorskip("fogsf.models.features")
nets = pytest.importorskip("fogsf.models.nets")
fit = pytest.importorskip("fogsf.training.net.loops")


@pytest.fixture(scope="session")
def kroot(tmp_path_factory):
    return tmp_path_factory.mktemp("kernels")


@pytest.mark.parametrize("layers, hidden, seed", [(1, 16, 0), (2, 7, 1)])
def test_trainer_network_and_kernel_agree(layers, hidden, seed, kroot) -> None:
    temp, gyro = samples.chamber_ramp(hours=3.0, seed=seed)
    spec = features.make_features(rate_tau_s=120.0)  # the paper's inputs: T and dT/dt
    fe = FrontEnd(t_ref_c=20.0, t_min_c=-45.0, t_max_c=60.0, decimation=20,
                     stuck_samples=3000,
                     filter_alpha=filter_alpha(list(spec.taus_s), 20))
    s = reference.frontend(temp, fe).s
    a = spec.matrix()
    raw = s.astype(np.float64) @ a.T
    norm = features.Normaliser((a / raw.std(axis=0)[:, None]).astype(np.float32),
                               (-raw.mean(axis=0) / raw.std(axis=0)).astype(np.float32))
    torch.manual_seed(seed)
    net = nets.StreamNet(spec.n_features, layers, hidden)
    with torch.no_grad():  # larger weights than the default init, so the LSTM works
        for p in net.lstm.parameters():
            p.mul_(3.0)
    offset, scale = 40.0, 300.0
    model = nets.to_stream_model(net, "lstm", spec, norm, fe, offset, scale)
    want = fit.predict_stream(net, norm.apply(s)) * scale + offset
    _, _, sf_c = trace_steps(kernel_for(model, kroot), temp, gyro)
    assert np.ptp(want) > 50, "the network barely moves"
    diff = np.abs(sf_c.astype(np.float64) - want)
    assert diff.max() <= 0.01, f"seed {seed}: {diff.max():.3g} ppm at step {np.argmax(diff)}"
