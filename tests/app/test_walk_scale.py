"""The shipped default random-walk scale (tracker/app/walk_scale.json) is what retargeting the shipped walks gives.

A change to retargeting, to the walks or to step_rms that changes the scale fails here: regenerate the file with
``python -m tracker.app.walk_scale``.
"""
from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from data_tools.samples import SAMPLES, sample_walks
from tracker.app import api, walk_scale
from tracker.app.walk_scale import (
    SHIPPED_FILE, SHIPPED_RATES, derive_walk_scale, shipped_walk_scale,
)
from tracker.core.body import fifteen_cone_model
from tracker.core.errors import InputError


def a_sequence(fps: float | None) -> SimpleNamespace:
    """What random_walk_scale reads of a sequence in the project's own layout at ``fps`` Hz."""
    return SimpleNamespace(layout="own", fps=fps, root="walk", model=fifteen_cone_model(), diffusion_std=None)


def refuse_to_derive(fps: float) -> np.ndarray:
    raise AssertionError(f"retargeted the walks at {fps} Hz, whose scale is shipped")


@pytest.mark.slow
@pytest.mark.parametrize("fps", SHIPPED_RATES)
def test_shipped_scale_is_a_fresh_derivation_bit_for_bit(fps):
    fresh = derive_walk_scale(fps)
    shipped = shipped_walk_scale(fps)
    assert shipped is not None and shipped.dtype == np.float64 and shipped.shape == fresh.shape == (40,)
    worst = float(np.max(np.abs(shipped - fresh) / np.abs(fresh)))
    # within rounding: another CPU's maths library may differ in the last bits; a change to retargeting moves
    # these numbers by far more
    assert worst < 1e-12, (f"the shipped scale at {fps:g} Hz differs from the walks' (worst "
                                            f"relative difference {worst:.3g}): python -m tracker.app.walk_scale")


def test_the_file_holds_the_shipped_rates_of_the_shipped_walks():
    content = json.loads(SHIPPED_FILE.read_text(encoding="utf-8"))
    assert sorted(float(r) for r in content["rates"]) == sorted(SHIPPED_RATES)
    asf, walks = sample_walks()
    assert content["walks"] == [p.relative_to(SAMPLES).as_posix() for p in (asf, *walks)]
    assert all(len(v) == 40 and all(x > 0 for x in v) for v in content["rates"].values())


def test_the_scale_depends_on_the_rate_beyond_one_over_fps():
    """Why each rate is shipped, or derived, at that rate: no rescaling of the 60 Hz scale gives the 30 Hz one."""
    ratio = shipped_walk_scale(30.0) / shipped_walk_scale(60.0)
    assert 1.0 < ratio.min() and ratio.max() < 2.1 and np.ptp(ratio) > 0.5  # 1.13 to 2.0 per dof


def test_a_shipped_rate_is_read_not_derived(monkeypatch):
    monkeypatch.setattr(walk_scale, "derive_walk_scale", refuse_to_derive)
    for fps in (60, 60.0, 25.0):
        assert np.array_equal(api.random_walk_scale(a_sequence(fps)), shipped_walk_scale(fps))
    api.random_walk_scale(a_sequence(60.0))[0] = -1.0  # a caller's changes do not reach the next run
    assert shipped_walk_scale(60.0)[0] > 0


def test_another_rate_is_derived_from_the_walks(monkeypatch):
    asked = []
    monkeypatch.setattr(walk_scale, "derive_walk_scale", lambda fps: asked.append(fps) or np.ones(40))
    assert shipped_walk_scale(29.97) is None
    assert np.array_equal(api.random_walk_scale(a_sequence(29.97)), np.ones(40))
    assert asked == [29.97]


@pytest.mark.slow
def test_given_training_clips_are_retargeted_not_looked_up(monkeypatch):
    """train_mocap derives the scale from those clips at the sequence's rate; given the shipped walks themselves
    it is the shipped scale."""
    monkeypatch.setattr(api, "walk_scale", refuse_to_derive)
    _, walks = sample_walks()
    from_clips = api.random_walk_scale(a_sequence(30.0), train_mocap=walks)
    assert np.array_equal(from_clips, shipped_walk_scale(30.0))
    assert not np.array_equal(api.random_walk_scale(a_sequence(30.0), train_mocap=walks[:1]), from_clips)


def test_a_sequence_without_a_frame_rate_is_refused():
    with pytest.raises(InputError, match="frame rate"):
        api.random_walk_scale(a_sequence(None))


def test_track_reads_the_shipped_scale(small_walk, monkeypatch):
    """A zero-velocity run at the synthetic sequences' 60 Hz retargets nothing and takes the shipped scale."""
    import tracker

    monkeypatch.setattr(walk_scale, "derive_walk_scale", refuse_to_derive)
    read = tracker.track(small_walk, "zero-velocity", particles=20, frames=3, seed=0)
    given = tracker.track(small_walk, "zero-velocity", particles=20, frames=3, seed=0,
                          step_std=shipped_walk_scale(60.0))
    assert np.array_equal(read.poses, given.poses)
