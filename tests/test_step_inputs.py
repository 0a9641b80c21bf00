"""The front end's step output and the training targets made a block at a time
(models/step_inputs.py): the same bits as the whole-log computation, on a log in memory and
on disk, with bad temperatures (NaN, out of range) across block borders."""

from __future__ import annotations

import numpy as np
import pytest
from test_metric_blocks import reversals

from fogsf.logs.measure import model_steps, windows
from fogsf.logs.measure.plateaus import measuring_mask
from fogsf.logs.read import columns
from fogsf.logs.read.stream_read import read_log_on_disk
from fogsf.logs.writer import write_log
from fogsf.models.features import front_end_for
from fogsf.models.reference import frontend
from fogsf.models.step_inputs import frontend_s, step_targets


def whole_targets(log, decimation: int) -> np.ndarray:  # noqa: ANN001 - the code it replaces
    m = measuring_mask(log)
    table = np.where(m, log.table_rate_dps, 1.0)
    ratio = np.where(m, windows.sf_signal(log) / table, 0.0)
    return (model_steps.step_means(ratio, decimation, m) - 1.0) * 1e6


PLAYS = (((0.5, 0.5, 0.0), 6.0), ((0.0, 0.25, 0.75), 2.5))  # two plays of lag mixes


@pytest.mark.parametrize("plays", [(), PLAYS], ids=["lags", "plays"])
@pytest.mark.parametrize("read", [37, 1 << 18])
def test_step_inputs_in_blocks_are_the_same_bits(read: int, plays, tmp_path,  # noqa: ANN001
                                                 monkeypatch) -> None:
    log = reversals()
    fe = front_end_for([log], 5.0, (300.0, 1200.0), plays=plays)
    assert fe.n_plays == len(plays)
    temp = log.temp_c.copy()
    temp[0:3] = np.nan  # no finite sample yet: t_ref
    temp[500:620] = np.nan  # the last finite one held across borders
    temp[900:905] = 400.0  # clamped
    ref_s = frontend(temp, fe).s
    want_t = whole_targets(log, fe.decimation)
    monkeypatch.setattr(columns, "READ_SAMPLES", read)
    assert np.array_equal(frontend_s(temp, fe), ref_s)
    assert np.array_equal(step_targets(log, fe.decimation), want_t, equal_nan=True)
    write_log(tmp_path / "log.csv", log)
    disk = read_log_on_disk(tmp_path / "log.csv")
    monkeypatch.setattr(columns, "STRICT", True)
    assert np.array_equal(frontend_s(disk.temp_c, fe), frontend(disk.temp_c[:], fe).s)
    from fogsf.logs.logio import read_log

    assert np.array_equal(step_targets(disk, fe.decimation),
                          whole_targets(read_log(tmp_path / "log.csv"), fe.decimation),
                          equal_nan=True)
