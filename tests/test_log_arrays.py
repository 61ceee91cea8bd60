"""Log.gyr/acc/mag/q_ref/dts/t are computed once (an update() loop written as log.gyr[i] must
not rebuild an (N, 3) array per sample), read-only, and recomputed when what they are made of
changes (a column replaced by calibration or alignment, dt, fixed_rate)."""
import numpy as np
import pytest

from imufuse.io import GYR, read_log, example_log


@pytest.fixture
def log():
    return read_log(example_log())


def test_computed_once_and_read_only(log):
    for name in ("gyr", "acc", "mag", "q_ref"):
        a = getattr(log, name)
        assert a is getattr(log, name)
        with pytest.raises(ValueError):
            a[0, 0] = 1.0
    assert np.array_equal(log.gyr, np.column_stack([log.columns[n] for n in GYR]))


def test_a_replaced_column_gives_a_new_array(log):
    g = log.gyr
    log.columns["gyr_x"] = log.columns["gyr_x"] + 1.0
    g2 = log.gyr
    assert g2 is not g and np.array_equal(g2[:, 0], g[:, 0] + 1.0)
    assert np.array_equal(g2[:, 1:], g[:, 1:])


def test_dts_follow_dt_and_fixed_rate(log):
    log.fixed_rate = False
    d = log.dts
    assert d is log.dts and d[0] == log.dt
    log.dt = 0.5
    assert log.dts[0] == 0.5
    log.fixed_rate = True
    assert log.dts is None
