"""Numba kernels behind the per-step calls of
:class:`ccm.learn.mixtures.forward_model.IncrementalForwardModel`: the feature scaling X / scale
fused with the IGMM update (:func:`ccm.learn.mixtures._igmm_kernels.fit_rows`) and with the GMR
prediction
(:func:`ccm.learn.mixtures._gmr_kernels.gmr_rows`), one compiled call each instead of a Python
layer,
numpy divisions and a product per call (a call from Python costs ~1 µs).

The scaling is the same IEEE division and product per entry as numpy's, so the model and
its predictions are bit for bit those of the unfused calls.
"""

from __future__ import annotations

from numba import njit

from ccm.learn.mixtures._chol_kernels import _JIT
from ccm.learn.mixtures._gmr_kernels import gmr_rows
from ccm.learn.mixtures._igmm_kernels import fit_rows


@njit(**_JIT)
def fit_scaled(s, d, scale, row, means, covs, chols, comp, istate, params, sigma2, work):
    """Learn the point [s, d] / scale (written into the (1, n) buffer ``row``); returns
    :func:`fit_rows`'s status (0, or -1 if the point is not finite: nothing changed)."""
    ns = s.shape[0]
    for i in range(ns):
        row[0, i] = s[i] / scale[i]
    for i in range(d.shape[0]):
        row[0, ns + i] = d[i] / scale[ns + i]
    return fit_rows(row, means, covs, chols, comp, istate, params, sigma2, work)


@njit(**_JIT)
def predict_scaled(s, scale, x_in, split, means, covs, comp, istate, cache, y, no_cov, out):
    """GMR mean for the input s / scale[:n_in] (via the (1, n_in) buffer ``x_in`` and the
    (1, n_out) buffer ``y``), times scale[n_in:], into ``out``; returns
    :func:`gmr_rows`'s status (0; -1 for an empty mixture, ``out`` untouched)."""
    ns = s.shape[0]
    for i in range(ns):
        x_in[0, i] = s[i] / scale[i]
    status = gmr_rows(x_in, split, means, covs, comp, istate, cache, y, no_cov, False)
    if status == 0:
        for r in range(out.shape[0]):
            out[r] = y[0, r] * scale[ns + r]
    return status


@njit(**_JIT)
def fit_predict_scaled(
    s, d, s_now, scale, row, x_in, y, no_cov, out,
    means, covs, chols, comp, istate, params, sigma2, work, split, cache,
):  # fmt: skip
    """:func:`fit_scaled` of [s, d], then :func:`predict_scaled` of ``s_now`` (one call for
    the two of a control step). Returns 1 if the point is not finite (nothing changed, no
    prediction), else :func:`gmr_rows`'s status."""
    if fit_scaled(s, d, scale, row, means, covs, chols, comp, istate, params, sigma2, work):
        return 1
    return predict_scaled(
        s_now, scale, x_in, split, means, covs, comp, istate, cache, y, no_cov, out
    )
