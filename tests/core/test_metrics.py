import numpy as np
import pytest

from tracker.core.errors import InputError
from tracker.core.metrics import marker_error, sequence_error, summarize_runs


def test_marker_error_by_hand():
    truth = np.zeros((2, 15, 3))
    est = np.zeros((2, 15, 3))
    est[0, :, 0] = 3.0  # every marker 3 mm off
    est[1, 0, :] = [3.0, 4.0, 0.0]  # one marker 5 mm off
    assert np.allclose(marker_error(est, truth), [3.0, 5.0 / 15])
    assert sequence_error(est, truth) == pytest.approx((3.0 + 5.0 / 15) / 2)


def test_root_aligned_ignores_translation(rng):
    truth = rng.normal(size=(4, 15, 3)) * 100
    est = truth + [50.0, -20.0, 10.0]
    assert np.allclose(marker_error(est, truth, root_aligned=True), 0)
    assert np.allclose(marker_error(est, truth), np.linalg.norm([50, -20, 10]))


def test_runs_summary():
    mean, std = summarize_runs([40.0, 42.0, 44.0])
    assert mean == pytest.approx(42.0) and std == pytest.approx(2.0)
    assert summarize_runs([7.0]) == (7.0, 0.0)


def test_bad_input():
    with pytest.raises(InputError, match="markers"):
        marker_error(np.zeros((15, 3)), np.zeros((14, 3)))
    with pytest.raises(InputError, match="NaN"):
        marker_error(np.full((15, 3), np.nan), np.zeros((15, 3)))
