"""Numba kernels behind :class:`ccm.learn.mixtures.igmm.IGMM` (the GMR kernels of
:class:`ccm.learn.mixtures.gmr.GMRConditional` are :mod:`ccm.learn.mixtures._gmr_kernels`).

Everything here works on preallocated buffers (no allocation in the per-step path) so that a
1 kHz control loop can call "update one point + GMR predict" in a few microseconds. The
Python classes own the buffers, validate inputs and turn the integer status codes returned
here into exceptions.

Mixture buffers (``Kmax`` = ``max_components``, ``d`` = ``n_features``); only the first
``K = istate[I_K]`` slots are live, in creation order:

* ``means`` (Kmax, d); ``covs`` (Kmax, d, d); ``chols`` (Kmax, d, d), lower Cholesky factors
  of ``covs`` with zeros above the diagonal;
* ``comp`` (N_COMP, Kmax) per-component scalars: ``comp[C_LOGDET]`` log det C_j,
  ``comp[C_SP]`` accumulated posterior support sp_j, ``comp[C_AGE]`` updates since creation
  v_j, ``comp[C_STAMP]`` a number that changes whenever mu_j, C_j or sp_j change (unique over
  the model's life, so it also tells a moved or replaced slot apart). All float64; counts
  are exact up to 2**53;
* ``istate`` int64 counters (``I_*``), ``params`` float64 settings (``P_*``).

Change stamps let the update skip refactorising covariances that did not change bitwise and
let a GMR cache refresh only the components that changed: with K = 20 most components have
a posterior so small that the update leaves them bit-for-bit as they were. Skipping is exact.

Small dense Cholesky factorisations and triangular solves are written out by hand: for
d <= 8 they are much faster than calling LAPACK through ``np.linalg``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# istate slots
I_K = 0  # live components
I_SEEN = 1  # points processed
I_VERSION = 2  # bumped on every model change (GMR caches compare against it)
I_CREATED = 3  # components created by the novelty test
I_MERGED = 4  # overflow merges
I_OVERFLOW_PRUNED = 5  # components dropped on overflow (overflow="prune")
I_SUPPORT_PRUNED = 6  # components removed by the v > v_min and sp < sp_min rule
I_JITTER = 7  # factorisations that needed extra diagonal loading (numerical safety net)
I_STAMP = 8  # last change stamp handed out
N_ISTATE = 9

# params slots
P_THRESHOLD = 0  # squared Mahalanobis novelty threshold (chi-square quantile)
P_FLOOR = 1  # covariance eigenvalue floor
P_SP_MIN = 2
P_V_MIN = 3
P_OVERFLOW = 4  # 0: merge, 1: prune
N_PARAMS = 5

OVERFLOW_MERGE = 0
OVERFLOW_PRUNE = 1

# comp rows
C_LOGDET = 0
C_SP = 1
C_AGE = 2
C_STAMP = 3
N_COMP = 4

_JIT = {"cache": True, "nogil": True, "error_model": "numpy"}


# ---------------------------------------------------------------------------------------------
# small dense linear algebra
# ---------------------------------------------------------------------------------------------


@njit(**_JIT)
def chol_into(a, out):
    """Lower Cholesky factor of ``a`` into ``out`` (zeros above); returns log det or NaN."""
    n = a.shape[0]
    prod = 1.0
    for j in range(n):
        s = a[j, j]
        for k in range(j):
            s -= out[j, k] * out[j, k]
        if not s > 0.0:
            return np.nan
        ljj = math.sqrt(s)
        out[j, j] = ljj
        prod *= ljj
        inv = 1.0 / ljj
        for i in range(j + 1, n):
            s = a[i, j]
            for k in range(j):
                s -= out[i, k] * out[j, k]
            out[i, j] = s * inv
        for i in range(j):
            out[i, j] = 0.0
    # one logarithm instead of n; sum of logs if the product under- or overflows
    if 1e-280 < prod < 1e280:
        return 2.0 * math.log(prod)
    acc = 0.0
    for j in range(n):
        acc += math.log(out[j, j])
    return 2.0 * acc


@njit(**_JIT)
def factor_with_floor(c, out, floor):
    """Cholesky of covariance ``c`` with a safety net; returns (log det, jitter used).

    The IGMM update keeps every eigenvalue >= ``floor`` by construction; rounding can still
    break a factorisation when ``floor`` is tiny relative to the scale of ``c``. Then the
    diagonal of ``c`` is raised (in place) by ``floor``, 2 ``floor``, 4 ``floor``, ... until
    the factorisation succeeds.
    """
    logdet = chol_into(c, out)
    if not math.isnan(logdet):
        return logdet, False
    n = c.shape[0]
    scale = 0.0
    for i in range(n):
        scale = max(scale, abs(c[i, i]))
    add = max(floor, 1e-15 * scale)
    for _ in range(200):
        for i in range(n):
            c[i, i] += add
        logdet = chol_into(c, out)
        if not math.isnan(logdet):
            return logdet, True
        add *= 2.0
    return np.nan, True


@njit(**_JIT)
def maha_sq(x, mu, chol, e, z):
    """Squared Mahalanobis distance of ``x`` to ``mu`` under ``chol @ chol.T``.

    Leaves ``e = x - mu`` and ``z = chol^-1 e`` in the work vectors.
    """
    n = x.shape[0]
    for i in range(n):
        e[i] = x[i] - mu[i]
    acc = 0.0
    for i in range(n):
        s = e[i]
        for k in range(i):
            s -= chol[i, k] * z[k]
        s /= chol[i, i]
        z[i] = s
        acc += s * s
    return acc


# ---------------------------------------------------------------------------------------------
# IGMM (Engel & Heinen 2010)
# ---------------------------------------------------------------------------------------------


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
