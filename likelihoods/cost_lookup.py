"""The CPU path's cost-map lookups of the edge + silhouette likelihood, compiled with numba.

Given the sample points of every cone in every view (pixel coordinates, from
:meth:`likelihoods.edge_silhouette.EdgeSilhouetteLikelihood._block_costs`), it reads the nearest pixel of the
padded cost maps and averages per particle and view: contour points read the edge map, grid points the
silhouette. The same steps as :meth:`likelihoods.edge_silhouette._CostMaps.flat_index` followed by an indexing
and a mean, which the device path runs as tensor operations, fused into one loop so that the CPU path writes no
index arrays (the likelihood alone: 11.7 -> 10.1 ms per 1000 particles x 4 views on one thread,
``docs/reference/performance.md``).
"""
from __future__ import annotations

import numpy as np
from numba import njit


def mean_costs(x: np.ndarray, y: np.ndarray, edge_map: np.ndarray, silhouette_map: np.ndarray,
               view_offset: np.ndarray, height: int, width: int, pad: float, n_contour: int,
               edge_out: np.ndarray, silhouette_out: np.ndarray) -> None:
    """Mean edge and silhouette costs of every particle in every view, written into ``edge_out`` and
    ``silhouette_out`` (float64, ``p x V``).

    ``x``, ``y`` ``V x p x S x N`` (float32 pixels of the unpadded image) are the ``N`` sample points of each of
    the ``S`` cones, the first ``n_contour`` on its contour lines. ``edge_map`` and ``silhouette_map`` (float32,
    flat) are the views' padded cost maps of ``height x width`` pixels each (the padded size: the image with a
    border of ``pad`` pixels of cost 1 around it), one after the other (view ``k`` starts at
    ``view_offset[k]``). A point reads the nearest pixel, clamped to the padded map (one that is not a number
    reads the border), in float32 as the device path computes it for finite points. The shapes and dtypes are
    checked here: the compiled loop reads and writes without bounds checks.
    """
    V, P, S, N = x.shape
    size = V * height * width
    floats = (x, y, edge_map, silhouette_map, edge_out, silhouette_out)
    if not (all(a.dtype.kind == "f" for a in floats) and view_offset.dtype.kind in "iu"):
        raise ValueError("cost lookup: points, maps and outputs must be floating-point arrays, offsets integers")
    if (y.shape != x.shape or S == 0 or not 0 < n_contour < N or view_offset.shape != (V,) or height < 1
            or width < 1
            or edge_out.shape != (P, V) or silhouette_out.shape != (P, V)
            or edge_map.shape != (size,) or silhouette_map.shape != (size,)
            or (V and not 0 <= view_offset.min() <= view_offset.max() <= size - height * width)):
        raise ValueError(f"cost lookup: inconsistent shapes (points {x.shape} and {y.shape}, maps "
                         f"{edge_map.shape} and {silhouette_map.shape} for {V} views of {height} x {width}, "
                         f"offsets {view_offset.shape}, outputs {edge_out.shape} and {silhouette_out.shape}, "
                         f"{n_contour} contour points)")
    _mean_costs(x, y, edge_map, silhouette_map, view_offset, height, width, pad, n_contour, edge_out,
                silhouette_out)


@njit(cache=True, nogil=True)
def _mean_costs(x, y, edge_map, silhouette_map, view_offset, height, width, pad, n_contour, edge_out,
                silhouette_out):
    """:func:`mean_costs`'s loop, over views, particles, cones and points."""
    V, P, S, N = x.shape
    shift = np.float32(pad + 0.5)
    x_max, y_max = np.float32(width - 1), np.float32(height - 1)
    zero = np.float32(0.0)
    n_edge, n_sil = S * n_contour, S * (N - n_contour)
    for k in range(V):
        offset = view_offset[k]
        for p in range(P):
            edge_sum, sil_sum = 0.0, 0.0
            for s in range(S):
                for n in range(N):
                    px = x[k, p, s, n] + shift
                    py = y[k, p, s, n] + shift
                    if px > x_max:
                        px = x_max
                    if not px >= zero:  # NaN too: the border, never a read outside the maps
                        px = zero
                    if py > y_max:
                        py = y_max
                    if not py >= zero:
                        py = zero
                    index = offset + int(py) * width + int(px)
                    if n < n_contour:
                        edge_sum += edge_map[index]
                    else:
                        sil_sum += silhouette_map[index]
            edge_out[p, k] = edge_sum / n_edge
            silhouette_out[p, k] = sil_sum / n_sil
