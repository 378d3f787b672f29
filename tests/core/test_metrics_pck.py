"""3DPCK, absolute and root-relative (MPI-INF-3DHP, mmpose), and the one set of metric names."""
import numpy as np
import pytest

from tracker.core.errors import InputError
from tracker.core.metrics import (
    METRICS, PCK_THRESHOLD_MM, PELVIS, frame_metrics, marker_error, pck, procrustes_aligned_error, root_relative_pck,
)


def pose(rng: np.random.Generator, frames: int = 1) -> np.ndarray:
    """Markers ``frames x 15 x 3`` (mm) spread like a body's: within about a metre of each other."""
    return rng.normal(size=(frames, 15, 3)) * 300.0


def test_a_translated_estimate_fails_absolute_pck_and_passes_root_relative_pck(rng):
    truth = pose(rng, 4)
    est = truth + [200.0, 0.0, 0.0]  # every marker 200 mm off, the articulation exact
    assert np.allclose(pck(est, truth), 0.0)
    assert np.allclose(root_relative_pck(est, truth), 100.0)


def test_root_relative_pck_by_hand(rng):
    truth = pose(rng)
    est = truth + [10.0, -30.0, 5.0]
    est[0, 4] += [0.0, 0.0, 149.0]  # 149 mm off after root alignment: correct
    est[0, 7] += [150.0, 0.0, 0.0]  # exactly 150 mm: not correct (strict, as mmpose and the 3DHP script)
    est[0, 9] += [0.0, 400.0, 0.0]
    assert root_relative_pck(est, truth)[0] == pytest.approx(100.0 * 13 / 15)
    assert root_relative_pck(est, truth, threshold_mm=150.001)[0] == pytest.approx(100.0 * 14 / 15)


def test_the_root_counts_as_a_marker_and_moving_it_moves_every_other(rng):
    truth = pose(rng)
    est = truth.copy()
    est[0, PELVIS] += [0.0, 0.0, 500.0]  # the root alone is wrong: after alignment every other marker is 500 mm off
    assert root_relative_pck(est, truth)[0] == pytest.approx(100.0 / 15)
    assert pck(est, truth)[0] == pytest.approx(100.0 * 14 / 15)
    assert root_relative_pck(est, truth, root=3)[0] == pytest.approx(100.0 * 14 / 15)


def test_pck_keeps_leading_batch_axes_and_checks_its_input(rng):
    truth = pose(rng, 6).reshape(2, 3, 15, 3)
    est = truth + rng.normal(size=truth.shape) * 100.0
    for f in (pck, root_relative_pck):
        values = f(est, truth)
        assert values.shape == (2, 3) and np.all((values >= 0) & (values <= 100))
        assert np.allclose(values[1, 2], f(est[1, 2], truth[1, 2]))
    with pytest.raises(InputError, match="markers"):
        root_relative_pck(np.zeros((15, 3)), np.zeros((14, 3)))
    with pytest.raises(InputError, match="NaN"):
        root_relative_pck(np.full((15, 3), np.nan), np.zeros((15, 3)))


def test_one_name_per_metric_and_frame_metrics_gives_each(rng):
    names = [m.name for m in METRICS]
    assert names == ["mpjpe_abs", "mpjpe_rel", "pa_mpjpe", "pck_abs", "pck_rel"] and PCK_THRESHOLD_MM == 150.0
    truth = pose(rng, 5)
    est = truth + rng.normal(size=truth.shape) * 60.0 + [80.0, 0.0, 0.0]
    values = frame_metrics(est, truth)
    assert list(values) == names and all(v.shape == (5,) for v in values.values())
    assert np.allclose(values["mpjpe_abs"], marker_error(est, truth))
    assert np.allclose(values["mpjpe_rel"], marker_error(est, truth, root_aligned=True))
    assert np.allclose(values["pa_mpjpe"], procrustes_aligned_error(est, truth))
    assert np.allclose(values["pck_abs"], pck(est, truth)) and np.allclose(values["pck_rel"], root_relative_pck(est, truth))
