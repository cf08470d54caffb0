"""Numba kernels behind :class:`ccm.learn.mixtures.gmr.GMRConditional`: Gaussian mixture
regression (Sung 2004; seed A Eq. 6) over the mixture buffers of
:mod:`ccm.learn.mixtures._igmm_layout`, with a per-split cache of the conditional factors
that is refreshed only for components whose change stamp moved.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ccm.learn.mixtures._chol_kernels import _JIT, chol_into, maha_sq
from ccm.learn.mixtures._igmm_layout import C_SP, C_STAMP, I_K, I_VERSION


def new_gmr_cache(kmax: int, di: int, do: int) -> np.ndarray:
    """A float64 cache buffer for :func:`gmr_rows` (one split), marked as empty."""
    factors = kmax * (di + do + di * di + 1 + do * di + do * do)
    work = max(di * di + di * do, 2 * di + kmax + kmax * do)
    cache = np.zeros(factors + kmax + 1 + work)
    cache[factors : factors + kmax + 1] = -1.0  # stamps and version: nothing cached yet
    return cache


@njit(**_JIT)
def _refresh_component(
    k, in_idx, out_idx, means, covs, weights, mu_in, mu_out, l_in, logw, reg, cond_cov, sbuf, wbuf
):
    """Conditioning factors of component ``k``; returns False if Sigma_in,in is singular."""
    di = in_idx.shape[0]
    do = out_idx.shape[0]
    for a in range(di):
        mu_in[k, a] = means[k, in_idx[a]]
        for b in range(di):
            sbuf[a, b] = covs[k, in_idx[a], in_idx[b]]
    for r in range(do):
        mu_out[k, r] = means[k, out_idx[r]]
    ld = chol_into(sbuf, l_in[k])
    if math.isnan(ld):
        return False
    lk = l_in[k]
    # W = L^-1 Sigma_in,out
    for r in range(do):
        for a in range(di):
            s = covs[k, in_idx[a], out_idx[r]]
            for c in range(a):
                s -= lk[a, c] * wbuf[c, r]
            wbuf[a, r] = s / lk[a, a]
    # regression matrix Sigma_out,in Sigma_in,in^-1: row r solves L^T a = W[:, r]
    for r in range(do):
        for a in range(di - 1, -1, -1):
            s = wbuf[a, r]
            for c in range(a + 1, di):
                s -= lk[c, a] * reg[k, r, c]
            reg[k, r, a] = s / lk[a, a]
    # conditional covariance Sigma_out,out - W^T W (symmetric by construction)
    for r in range(do):
        for s2 in range(r + 1):
            acc = covs[k, out_idx[r], out_idx[s2]]
            for a in range(di):
                acc -= wbuf[a, r] * wbuf[a, s2]
            cond_cov[k, r, s2] = acc
            cond_cov[k, s2, r] = acc
    logw[k] = math.log(weights[k]) - 0.5 * ld
    return True


@njit(**_JIT)
def gmr_rows(X, split, means, covs, comp, istate, cache, out_mean, out_cov, want_cov):
    """GMR conditional mean (and covariance) of ``x_out`` given each row of ``X``.

    mean = sum_k h_k(x) m_k(x), m_k = mu_out,k + Sigma_out,in,k Sigma_in,in,k^-1 (x - mu_in,k),
    h_k proportional to p(k) N(x | mu_in,k, Sigma_in,in,k); cov = sum_k h_k (S_k + (m_k -
    mean)(m_k - mean)^T) with S_k the conditional covariance of component k.

    ``split`` = [n_in, n_out, in_idx..., out_idx...]. ``cache`` (see :func:`gmr_cache_size`)
    holds per-component factors; those of a component are recomputed only when its change
    stamp differs from the cached one, and none are looked at when the model version has not
    changed. Returns 0; -1 if the mixture is empty; -2 - k if component k has a singular
    input block; -(10 + i) if row i of ``X`` is not finite.
    """
    n = istate[I_K]
    if n == 0:
        return -1
    n_rows = X.shape[0]
    di = split[0]
    do = split[1]
    in_idx = split[2 : 2 + di]
    out_idx = split[2 + di : 2 + di + do]
    kmax = means.shape[0]
    for i in range(n_rows):
        for a in range(di):
            if not math.isfinite(X[i, a]):
                return -(10 + i)
    # carve the cache
    o = 0
    mu_in = cache[o : o + kmax * di].reshape((kmax, di))
    o += kmax * di
    mu_out = cache[o : o + kmax * do].reshape((kmax, do))
    o += kmax * do
    l_in = cache[o : o + kmax * di * di].reshape((kmax, di, di))
    o += kmax * di * di
    logw = cache[o : o + kmax]
    o += kmax
    reg = cache[o : o + kmax * do * di].reshape((kmax, do, di))
    o += kmax * do * di
    cond_cov = cache[o : o + kmax * do * do].reshape((kmax, do, do))
    o += kmax * do * do
    stamps = cache[o : o + kmax]
    o += kmax
    version = o
    o += 1
    work = cache[o:]
    if cache[version] != istate[I_VERSION]:
        sbuf = work[0 : di * di].reshape((di, di))
        wbuf = work[di * di : di * di + di * do].reshape((di, do))
        for k in range(n):
            if stamps[k] != comp[C_STAMP, k]:
                ok = _refresh_component(
                    k,
                    in_idx,
                    out_idx,
                    means,
                    covs,
                    comp[C_SP],
                    mu_in,
                    mu_out,
                    l_in,
                    logw,
                    reg,
                    cond_cov,
                    sbuf,
                    wbuf,
                )
                if not ok:
                    stamps[k] = -1.0
                    cache[version] = -1.0
                    return -2 - k
                stamps[k] = comp[C_STAMP, k]
        cache[version] = istate[I_VERSION]
    diff = work[0:di]
    z = work[di : 2 * di]
    h = work[2 * di : 2 * di + kmax]
    m = work[2 * di + kmax : 2 * di + kmax + kmax * do].reshape((kmax, do))
    for row in range(n_rows):
        x = X[row]
        best = -np.inf
        for k in range(n):
            m2 = maha_sq(x, mu_in[k], l_in[k], diff, z)
            v = logw[k] - 0.5 * m2
            h[k] = v
            if v > best:
                best = v
            for r in range(do):
                acc = mu_out[k, r]
                for a in range(di):
                    acc += reg[k, r, a] * diff[a]
                m[k, r] = acc
        total = 0.0
        for k in range(n):
            p = math.exp(h[k] - best)
            h[k] = p
            total += p
        for r in range(do):
            out_mean[row, r] = 0.0
        for k in range(n):
            hk = h[k] / total
            h[k] = hk
            for r in range(do):
                out_mean[row, r] += hk * m[k, r]
        if want_cov:
            for r in range(do):
                for s in range(r + 1):
                    acc = 0.0
                    for k in range(n):
                        acc += h[k] * (
                            cond_cov[k, r, s]
                            + (m[k, r] - out_mean[row, r]) * (m[k, s] - out_mean[row, s])
                        )
                    out_cov[row, r, s] = acc
                    out_cov[row, s, r] = acc
    return 0
