"""correlate_symmetric against its independent truth, scipy.ndimage.correlate1d with zero padding: bit for bit."""

import numpy as np
import pytest
from scipy import ndimage

from harness.core import correlate as corr
from harness.core.correlate import correlate_symmetric
from harness.metrics.ssim import gaussian_taps

KERNELS = {"ssim gaussian": gaussian_taps(), "binomial": np.array([0.25, 0.5, 0.25]), "identity": np.array([1.0]),
           "wider than the data": np.exp(-0.5 * (np.arange(-9, 10) / 3.0) ** 2)}


@pytest.mark.parametrize("shape", [(2, 1, 3, 48, 64), (3, 1, 3, 7, 5), (24, 24, 24), (1, 1), (5,), (3, 0, 4)])
@pytest.mark.parametrize("kernel", list(KERNELS))
def test_equals_scipy_bit_for_bit_along_every_axis(shape, kernel):
    x = np.random.default_rng(len(shape)).normal(0, 10, shape)
    for axis in range(len(shape)):
        want = ndimage.correlate1d(x, KERNELS[kernel], axis=axis, mode="constant", cval=0.0)
        got = correlate_symmetric(x, KERNELS[kernel], axis)
        assert got.shape == x.shape and got.flags.c_contiguous and np.array_equal(got, want)


def test_blocks_do_not_change_a_value(monkeypatch):
    x = np.random.default_rng(1).random((3, 2, 40, 50))
    whole = [correlate_symmetric(x, gaussian_taps(), axis) for axis in (-1, -2)]
    monkeypatch.setattr(corr, "BLOCK_BYTES", 1)  # one leading row per block
    assert all(np.array_equal(correlate_symmetric(x, gaussian_taps(), axis), w) for axis, w in zip((-1, -2), whole))


def test_input_is_left_alone_and_other_kinds_are_refused():
    x = np.random.default_rng(2).random((6, 7))
    before = x.copy()
    correlate_symmetric(x, gaussian_taps(), 0)
    assert np.array_equal(x, before)
    for bad in (np.array([0.2, 0.8]), np.array([0.1, 0.5, 0.4]), np.ones((3, 3))):
        with pytest.raises(ValueError, match="symmetric kernel of odd length"):
            correlate_symmetric(x, bad, 0)
