"""Compiled per-cell loops of :mod:`ccm.sim.footprint` (issue #20).

The footprint friction visits every cell of an n × n grid over the tool face (n = 32 by
default: 1024 cells) once per physics step; as numpy expressions that was ~4 boolean arrays
per patch plus the pressure field. The two functions here do one pass over the cells with the
same IEEE operations in the same order (so the same values); the reductions (the weights'
sum and their dot with μ) stay numpy's, in the caller.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def friction_at(x: np.ndarray, y: np.ndarray, patches: np.ndarray, base: float) -> np.ndarray:
    """μ of the table at points (x, y): the first patch ``(x0, x1, y0, y1, μ)`` (rows of
    ``patches``) containing a point (edges included), else ``base``."""
    mu = np.full(x.shape[0], base)
    for i in range(x.shape[0]):
        for p in range(patches.shape[0]):
            if patches[p, 0] <= x[i] <= patches[p, 1] and patches[p, 2] <= y[i] <= patches[p, 3]:
                mu[i] = patches[p, 4]
                break
    return mu


@njit(cache=True)
def cell_weights_and_friction(
    center: np.ndarray,
    axes: np.ndarray,
    xi: np.ndarray,
    eta: np.ndarray,
    size: tuple[float, float],
    cop: tuple[float, float],
    patches: np.ndarray,
    base: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Per cell (ξ, η) of the face: the linear pressure ``1 + 12 c_ξ ξ / w² + 12 c_η η / d²``
    clipped at 0 (lift-off; not normalised), and μ of the table under the cell, whose table
    position is ``center[:2] + axes[:2] @ (ξ, η)``."""
    width, depth = size
    kx, ky = 12.0 * cop[0], 12.0 * cop[1]
    w2, d2 = width**2, depth**2
    n = xi.shape[0]
    w = np.empty(n)
    cx, cy = np.empty(n), np.empty(n)
    for i in range(n):
        p = 1.0 + kx * xi[i] / w2 + ky * eta[i] / d2
        w[i] = p if p > 0.0 else 0.0
        cx[i] = center[0] + (axes[0, 0] * xi[i] + axes[0, 1] * eta[i])
        cy[i] = center[1] + (axes[1, 0] * xi[i] + axes[1, 1] * eta[i])
    return w, friction_at(cx, cy, patches, base)
