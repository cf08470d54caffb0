"""Numba kernels that change the set of IGMM components (Engel & Heinen 2010): create a
component for a novel point, make room on overflow (merge the closest pair by moment matching,
Runnalls 2007, or drop the least supported one) and remove the components that failed the
support test. Called by the update step of :mod:`ccm.learn.mixtures._igmm_kernels`; the
buffers are laid out as :mod:`ccm.learn.mixtures._igmm_layout` describes.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ccm.learn.mixtures._chol_kernels import _JIT, chol_into, factor_with_floor
from ccm.learn.mixtures._igmm_layout import (
    C_AGE,
    C_LOGDET,
    C_SP,
    C_STAMP,
    I_CREATED,
    I_JITTER,
    I_K,
    I_MERGED,
    I_OVERFLOW_PRUNED,
    I_STAMP,
    I_SUPPORT_PRUNED,
    N_COMP,
    P_FLOOR,
    P_SP_MIN,
    P_V_MIN,
)


@njit(**_JIT)
def _new_stamp(istate):
    istate[I_STAMP] += 1
    return float(istate[I_STAMP])


@njit(**_JIT)
def _copy_slot(src, dst, means, covs, chols, comp):
    d = means.shape[1]
    for i in range(d):
        means[dst, i] = means[src, i]
        for j in range(d):
            covs[dst, i, j] = covs[src, i, j]
            chols[dst, i, j] = chols[src, i, j]
    for r in range(N_COMP):
        comp[r, dst] = comp[r, src]


@njit(**_JIT)
def _remove_slot(k, means, covs, chols, comp, istate):
    """Remove component ``k``, shifting the later ones down (keeps creation order)."""
    n = istate[I_K]
    for i in range(k, n - 1):
        _copy_slot(i + 1, i, means, covs, chols, comp)
    istate[I_K] = n - 1


@njit(**_JIT)
def _create(x, means, covs, chols, comp, istate, sigma2):
    """New component mu = x, C = diag(sigma_init^2), v = 1, sp = 1 (Engel & Heinen 2010)."""
    k = istate[I_K]
    d = x.shape[0]
    logdet = 0.0
    for i in range(d):
        means[k, i] = x[i]
        for j in range(d):
            covs[k, i, j] = 0.0
            chols[k, i, j] = 0.0
        covs[k, i, i] = sigma2[i]
        chols[k, i, i] = math.sqrt(sigma2[i])
        logdet += math.log(sigma2[i])
    comp[C_LOGDET, k] = logdet
    comp[C_SP, k] = 1.0
    comp[C_AGE, k] = 1.0
    comp[C_STAMP, k] = _new_stamp(istate)
    istate[I_K] = k + 1
    istate[I_CREATED] += 1


@njit(**_JIT)
def _merged_cov(i, j, means, covs, a, b, out):
    """Moment-matched covariance a C_i + b C_j + a b (mu_i - mu_j)(mu_i - mu_j)^T (a + b = 1)."""
    d = means.shape[1]
    ab = a * b
    for r in range(d):
        dr = means[i, r] - means[j, r]
        for s in range(r + 1):
            v = a * covs[i, r, s] + b * covs[j, r, s] + ab * dr * (means[i, s] - means[j, s])
            out[r, s] = v
            out[s, r] = v


@njit(**_JIT)
def _merge_closest(means, covs, chols, comp, istate, params, cbuf, lbuf):
    """Moment-match the pair with the smallest Runnalls (2007) KL upper bound into one slot.

    B(i, j) = 1/2 [(w_i + w_j) log det C_ij - w_i log det C_i - w_j log det C_j] with the
    supports sp as (unnormalised) weights and C_ij the moment-matched covariance.
    """
    n = istate[I_K]
    d = means.shape[1]
    sp = comp[C_SP]
    logdets = comp[C_LOGDET]
    best = np.inf
    bi = 0
    bj = 1
    for i in range(n):
        for j in range(i + 1, n):
            w = sp[i] + sp[j]
            _merged_cov(i, j, means, covs, sp[i] / w, sp[j] / w, cbuf)
            ld = chol_into(cbuf, lbuf)
            if math.isnan(ld):
                continue
            cost = 0.5 * (w * ld - sp[i] * logdets[i] - sp[j] * logdets[j])
            if cost < best:
                best = cost
                bi = i
                bj = j
    w = sp[bi] + sp[bj]
    a = sp[bi] / w
    b = sp[bj] / w
    _merged_cov(bi, bj, means, covs, a, b, cbuf)
    for r in range(d):
        means[bi, r] = a * means[bi, r] + b * means[bj, r]
        for s in range(d):
            covs[bi, r, s] = cbuf[r, s]
    ld, jit = factor_with_floor(covs[bi], chols[bi], params[P_FLOOR])
    if jit:
        istate[I_JITTER] += 1
    comp[C_LOGDET, bi] = ld
    comp[C_SP, bi] = w
    comp[C_AGE, bi] = max(comp[C_AGE, bi], comp[C_AGE, bj])
    comp[C_STAMP, bi] = _new_stamp(istate)
    _remove_slot(bj, means, covs, chols, comp, istate)
    istate[I_MERGED] += 1


@njit(**_JIT)
def _drop_least_support(means, covs, chols, comp, istate):
    n = istate[I_K]
    sp = comp[C_SP]
    k = 0
    for i in range(1, n):
        if sp[i] < sp[k]:
            k = i
    _remove_slot(k, means, covs, chols, comp, istate)
    istate[I_OVERFLOW_PRUNED] += 1


@njit(**_JIT)
def _prune_support(means, covs, chols, comp, istate, params):
    """Remove components with v_j > v_min and sp_j < sp_min; never removes the last one."""
    n = istate[I_K]
    v_min = params[P_V_MIN]
    sp_min = params[P_SP_MIN]
    sp = comp[C_SP]
    age = comp[C_AGE]
    n_bad = 0
    keep = 0
    for i in range(n):
        if age[i] > v_min and sp[i] < sp_min:
            n_bad += 1
            if n_bad == 1 or sp[i] > sp[keep]:
                keep = i
    if n_bad == 0:
        return
    spare = n_bad == n  # all would go: keep the best supported one
    w = 0
    for i in range(n):
        if age[i] > v_min and sp[i] < sp_min and not (spare and i == keep):
            istate[I_SUPPORT_PRUNED] += 1
            continue
        if w != i:
            _copy_slot(i, w, means, covs, chols, comp)
        w += 1
    istate[I_K] = w
