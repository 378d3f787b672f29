"""The CPU path's compiled cost-map lookups against a plain numpy statement of what they compute."""
import numpy as np

from likelihoods.cost_lookup import mean_costs

PAD = 4


def _maps(rng, views: int, height: int, width: int) -> np.ndarray:
    """Padded cost maps ``V x Hp x Wp``: random inner costs, a border of cost 1."""
    maps = np.ones((views, height + 2 * PAD, width + 2 * PAD), np.float32)
    maps[:, PAD:-PAD, PAD:-PAD] = rng.uniform(0, 1, (views, height, width))
    return maps


def _reference(x, y, edge, sil, n_contour):
    """Nearest padded pixel of every point (clamped to the map), means per particle and view ``p x V``."""
    V, Hp, Wp = edge.shape
    ix = np.clip(x + PAD + 0.5, 0, Wp - 1).astype(int)
    iy = np.clip(y + PAD + 0.5, 0, Hp - 1).astype(int)
    view = np.arange(V)[:, None, None, None]
    P = x.shape[1]
    return (edge[view, iy, ix][..., :n_contour].reshape(V, P, -1).mean(-1).T,
            sil[view, iy, ix][..., n_contour:].reshape(V, P, -1).mean(-1).T)


def test_compiled_lookups_equal_the_plain_statement_and_read_the_border_off_the_image():
    rng = np.random.default_rng(3)
    V, P, S, N, n_contour, H, W = 3, 40, 5, 14, 6, 30, 50
    # points on quarter pixels (no rounding ambiguity), some off the image on every side
    x = (rng.integers(-40, 4 * (W + 10), (V, P, S, N)) / 4.0).astype(np.float32)
    y = (rng.integers(-40, 4 * (H + 10), (V, P, S, N)) / 4.0).astype(np.float32)
    edge_maps, sil_maps = _maps(rng, V, H, W), _maps(rng, V, H, W)
    Hp, Wp = H + 2 * PAD, W + 2 * PAD
    offset = np.arange(V, dtype=np.int32) * Hp * Wp
    edge, sil = np.empty((P, V)), np.empty((P, V))

    def lookup(xx, yy):
        mean_costs(xx, yy, edge_maps.ravel(), sil_maps.ravel(), offset, Hp, Wp, float(PAD), n_contour, edge, sil)

    lookup(x, y)
    want_edge, want_sil = _reference(x, y, edge_maps, sil_maps, n_contour)
    np.testing.assert_allclose(edge, want_edge, atol=1e-6)
    np.testing.assert_allclose(sil, want_sil, atol=1e-6)
    assert not np.all(edge == 1.0)

    far = np.full_like(x, 1e7)  # points beyond the maps on any side, and points that are not numbers: the border
    for xx, yy in ((far, y), (-far, y), (x, far), (x, -far), (np.full_like(x, np.nan), y), (x, far * np.nan)):
        lookup(xx, yy)
        assert np.all(edge == 1.0) and np.all(sil == 1.0)
