"""The CPU path's compiled cost-map lookups against the device path's indexing, run on numpy arrays."""
import numpy as np
import pytest

from likelihoods.cost_lookup import mean_costs
from likelihoods.edge_silhouette import PAD, _CostMaps


def _maps(rng, views: int, height: int, width: int) -> np.ndarray:
    """Padded cost maps ``V x Hp x Wp``: random inner costs, a border of cost 1."""
    maps = np.ones((views, height + 2 * PAD, width + 2 * PAD), np.float32)
    maps[:, PAD:-PAD, PAD:-PAD] = rng.uniform(0, 1, (views, height, width))
    return maps


def test_compiled_lookups_equal_the_device_paths_indexing_and_read_the_border_off_the_image():
    rng = np.random.default_rng(3)
    V, P, S, N, n_contour, H, W = 3, 40, 5, 14, 6, 30, 50
    # points on quarter pixels and on pixel boundaries, some off the image on every side
    x = (rng.integers(-4 * (PAD + 10), 4 * (W + PAD + 10), (V, P, S, N)) / 4.0).astype(np.float32)
    y = (rng.integers(-4 * (PAD + 10), 4 * (H + PAD + 10), (V, P, S, N)) / 4.0).astype(np.float32)
    edge_maps, sil_maps = _maps(rng, V, H, W), _maps(rng, V, H, W)
    Hp, Wp = H + 2 * PAD, W + 2 * PAD
    maps = _CostMaps(edge_maps.ravel(), sil_maps.ravel(), [], np.arange(V, dtype=np.int64) * Hp * Wp, Hp, Wp)
    edge, sil = np.empty((P, V)), np.empty((P, V))

    def lookup(xx, yy):
        mean_costs(xx, yy, maps.edge, maps.silhouette, maps.view_offset, Hp, Wp, float(PAD), n_contour, edge, sil)

    lookup(x, y)
    flat = maps.flat_index(x.copy(), y.copy())  # the device path's indices, V x P x S x N
    want_edge = maps.edge[flat[..., :n_contour]].reshape(V, P, -1).mean(-1).T
    want_sil = maps.silhouette[flat[..., n_contour:]].reshape(V, P, -1).mean(-1).T
    np.testing.assert_allclose(edge, want_edge, atol=1e-6)
    np.testing.assert_allclose(sil, want_sil, atol=1e-6)
    assert not np.all(edge == 1.0)

    far = np.full_like(x, 1e7)  # points beyond the maps on any side, and points that are not numbers: the border
    for xx, yy in ((far, y), (-far, y), (x, far), (x, -far), (np.full_like(x, np.nan), y), (x, far * np.nan)):
        lookup(xx, yy)
        assert np.all(edge == 1.0) and np.all(sil == 1.0)

    bad = {"outputs the wrong way round": dict(edge=np.empty((V, P))),
           "too few offsets": dict(offset=maps.view_offset[:2]),
           "an offset past the maps": dict(offset=maps.view_offset + Hp * Wp),
           "no contour points": dict(n_contour=0),
           "maps of another size": dict(Hp=Hp + 1),
           "maps of no height": dict(Hp=0),
           "integer outputs": dict(edge=np.empty((P, V), np.int64))}
    for change in bad.values():
        with pytest.raises(ValueError, match="inconsistent shapes|floating-point"):
            mean_costs(x, y, maps.edge, maps.silhouette, change.get("offset", maps.view_offset), change.get("Hp", Hp),
                       Wp, float(PAD), change.get("n_contour", n_contour), change.get("edge", edge), sil)
