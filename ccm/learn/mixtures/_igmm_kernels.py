"""Numba kernels behind :class:`ccm.learn.mixtures.igmm.IGMM` (the GMR kernels of
:class:`ccm.learn.mixtures.gmr.GMRConditional` are :mod:`ccm.learn.mixtures._gmr_kernels`):
the Engel & Heinen (2010) update of one point, a batch of points, refactorising restored
components, and the log density of seed A Eq. 5.

Everything here works on preallocated buffers (no allocation in the per-step path) so that a
1 kHz control loop can call "update one point + GMR predict" in a few microseconds. The
Python classes own the buffers, validate inputs and turn the integer status codes returned
here into exceptions. The buffers are laid out as :mod:`ccm.learn.mixtures._igmm_layout`
describes; creating, merging and pruning components is :mod:`._igmm_slot_kernels`, the small
dense linear algebra :mod:`._chol_kernels`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ccm.learn.mixtures._chol_kernels import _JIT, chol_into, factor_with_floor, maha_sq
from ccm.learn.mixtures._igmm_layout import (
    C_AGE,
    C_LOGDET,
    C_SP,
    C_STAMP,
    I_JITTER,
    I_K,
    I_SEEN,
    I_VERSION,
    OVERFLOW_MERGE,
    P_FLOOR,
    P_OVERFLOW,
    P_THRESHOLD,
)
from ccm.learn.mixtures._igmm_slot_kernels import (
    _create,
    _drop_least_support,
    _merge_closest,
    _new_stamp,
    _prune_support,
)


@njit(**_JIT)
def _update_one(x, means, covs, chols, comp, istate, params, sigma2, work):
    """One Engel & Heinen (2010) step: novelty test, then create or update all components."""
    d = x.shape[0]
    kmax = means.shape[0]
    n = istate[I_K]
    e = work[0:d]
    z = work[d : 2 * d]
    logp = work[2 * d : 2 * d + kmax]
    cbuf = work[2 * d + kmax : 2 * d + kmax + d * d].reshape((d, d))
    lbuf = work[2 * d + kmax + d * d : 2 * d + kmax + 2 * d * d].reshape((d, d))
    threshold = params[P_THRESHOLD]
    floor = params[P_FLOOR]
    sp = comp[C_SP]
    age = comp[C_AGE]

    novel = True
    best = -np.inf
    for j in range(n):
        m2 = maha_sq(x, means[j], chols[j], e, z)
        if m2 < threshold:
            novel = False
        # log p(x|j) p(j) up to terms common to all j (Eq. 5)
        lp = math.log(sp[j]) - 0.5 * comp[C_LOGDET, j] - 0.5 * m2
        logp[j] = lp
        if lp > best:
            best = lp

    if novel:
        if n >= kmax:
            if params[P_OVERFLOW] == OVERFLOW_MERGE:
                _merge_closest(means, covs, chols, comp, istate, params, cbuf, lbuf)
            else:
                _drop_least_support(means, covs, chols, comp, istate)
        _create(x, means, covs, chols, comp, istate, sigma2)
    else:
        total = 0.0
        for j in range(n):
            p = math.exp(logp[j] - best)
            logp[j] = p
            total += p
        for j in range(n):
            post = logp[j] / total  # p(j|x)
            age[j] += 1.0
            if post == 0.0:
                continue  # underflow: sp_j, mu_j and C_j stay exactly as they are
            new_sp = sp[j] + post
            changed = new_sp != sp[j]
            sp[j] = new_sp
            w = post / new_sp  # omega_j
            for i in range(d):
                e[i] = x[i] - means[j, i]  # e = x - mu_j(old)
                m = means[j, i] + w * e[i]
                if m != means[j, i]:
                    changed = True
                    means[j, i] = m
            # exact weighted-moment update, C <- (1-w) C + w (1-w) e e^T, plus w * floor * I so
            # that lambda_min(C) >= floor is kept by induction (convex combination)
            a = 1.0 - w
            b = w * a
            wf = w * floor
            cov_changed = False
            for r in range(d):
                for s in range(r + 1):
                    v = a * covs[j, r, s] + b * e[r] * e[s]
                    if r == s:
                        v += wf
                    if v != covs[j, r, s]:
                        cov_changed = True
                        covs[j, r, s] = v
                        covs[j, s, r] = v
            if cov_changed:  # otherwise the factor is still exact
                changed = True
                ld, jit = factor_with_floor(covs[j], chols[j], floor)
                if jit:
                    istate[I_JITTER] += 1
                comp[C_LOGDET, j] = ld
            if changed:
                comp[C_STAMP, j] = _new_stamp(istate)
        _prune_support(means, covs, chols, comp, istate, params)
    istate[I_SEEN] += 1
    istate[I_VERSION] += 1


@njit(**_JIT)
def fit_rows(X, means, covs, chols, comp, istate, params, sigma2, work):
    """Process the rows of ``X`` in order. Returns 0, or -(i + 1) if row i is not finite.

    The whole batch is checked before the model is touched, so a bad row changes nothing.
    """
    n_rows, d = X.shape
    for i in range(n_rows):
        for j in range(d):
            if not math.isfinite(X[i, j]):
                return -(i + 1)
    for i in range(n_rows):
        _update_one(X[i], means, covs, chols, comp, istate, params, sigma2, work)
    return 0


@njit(**_JIT)
def refactor_all(n, covs, chols, comp, istate):
    """Recompute Cholesky factors, log-dets and stamps of the first ``n`` components.

    Returns the index of the first covariance that is not positive definite, or -1.
    """
    for k in range(n):
        ld = chol_into(covs[k], chols[k])
        if math.isnan(ld):
            return k
        comp[C_LOGDET, k] = ld
        comp[C_STAMP, k] = _new_stamp(istate)
    istate[I_VERSION] += 1
    return -1


@njit(**_JIT)
def score_rows(X, n, means, chols, comp, work, out):
    """log sum_j p(j) N(x | mu_j, C_j) for each row of ``X`` into ``out`` (Eq. 5 summand)."""
    n_rows, d = X.shape
    e = work[0:d]
    z = work[d : 2 * d]
    lp = work[2 * d : 2 * d + n]
    sp = comp[C_SP]
    total_sp = 0.0
    for j in range(n):
        total_sp += sp[j]
    const = -0.5 * d * math.log(2.0 * math.pi) - math.log(total_sp)
    for r in range(n_rows):
        best = -np.inf
        for j in range(n):
            m2 = maha_sq(X[r], means[j], chols[j], e, z)
            v = math.log(sp[j]) - 0.5 * comp[C_LOGDET, j] - 0.5 * m2
            lp[j] = v
            if v > best:
                best = v
        acc = 0.0
        for j in range(n):
            acc += math.exp(lp[j] - best)
        out[r] = const + best + math.log(acc)
