"""The random-walk priors (priors/random_walk.py); ``isotropic_ground`` gives the root one ground noise in every
direction, so a baseline whose scale came from clips that all walk along one axis does not follow a person along
that axis only."""
import numpy as np
import pytest

from priors.random_walk import isotropic_ground
from tracker.core.body import DOF_NAMES, fifteen_cone_model
from tracker.core.errors import InputError
from tracker.core.parsec_body import BODYTRACK_DOF_NAMES
from tracker.engine.registry import PRIORS, PriorContext


def test_the_ground_coordinates_get_the_rms_of_their_scales():
    std = np.linspace(0.01, 0.4, len(DOF_NAMES))
    std[:3] = [1.5, 20.0, 2.0]  # along x, along y (the training walks' direction), height
    out = isotropic_ground(std, DOF_NAMES)
    assert out[:2] == pytest.approx([np.sqrt((1.5 ** 2 + 20.0 ** 2) / 2)] * 2)
    assert np.array_equal(out[2:], std[2:]) and std[0] == 1.5  # the rest unchanged, the input untouched
    assert np.sum(out[:2] ** 2) == pytest.approx(np.sum(std[:2] ** 2))  # the same total ground spread


def test_a_layout_without_root_ground_coordinates_is_refused():
    with pytest.raises(InputError, match="root_x, root_y"):
        isotropic_ground(np.ones(len(BODYTRACK_DOF_NAMES)), BODYTRACK_DOF_NAMES)


@pytest.mark.parametrize("name", ["zero-velocity", "constant-velocity"])
def test_the_random_walk_priors_take_the_option(name):
    std = np.full(len(DOF_NAMES), 0.02)
    std[:2] = [1.5, 20.0]
    context = PriorContext(fifteen_cone_model(), 60.0, step_std_source=lambda: std)
    entry = PRIORS.get(name)
    default = entry.build(context, [], {"prior_scale": 2.0, "isotropic_ground": False})
    even = entry.build(context, [], {"prior_scale": 2.0, "isotropic_ground": True})
    assert np.allclose(default.std[:2], [3.0, 40.0])
    assert np.allclose(even.std[:2], 2 * np.sqrt((1.5 ** 2 + 20.0 ** 2) / 2))
    assert {o.name: o for o in entry.options}["isotropic_ground"].default is False
