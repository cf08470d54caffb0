"""Gaussian mixture regression (GMR; Sung 2004), seed A Eq. 6.

Conditioning a Gaussian mixture p(x) = sum_k p(k) N(x | mu_k, Sigma_k) on some of its
dimensions ``x_in`` gives another mixture over ``x_out``:

* component weights h_k(x_in) proportional to p(k) N(x_in | mu_in,k, Sigma_in,in,k),
* component means m_k(x_in) = mu_out,k + Sigma_out,in,k Sigma_in,in,k^-1 (x_in - mu_in,k),
* component covariances S_k = Sigma_out,out,k - Sigma_out,in,k Sigma_in,in,k^-1 Sigma_in,out,k.

GMR predicts its mean E[x_out | x_in] = sum_k h_k m_k (seed A's forward model f_fm, Eq. 6)
and, collapsed to one Gaussian, its covariance sum_k h_k (S_k + (m_k - mean)(m_k - mean)^T):
the mixture of conditional covariances plus the spread of the conditional means.

Two entry points:

* :func:`gmr_predict` — plain numpy, batch, no state; works on any mixture given as
  ``(weights, means, covariances)``, e.g. a frozen scikit-learn ``GaussianMixture``
  (``gm.weights_, gm.means_, gm.covariances_`` with ``covariance_type="full"``).
* :class:`GMRConditional` — the same maths with the per-component factorisations cached and
  numba kernels for the per-step path (a few microseconds per prediction). It is what
  :meth:`ccm.learn.mixtures.igmm.IGMM.conditional` returns; built directly it wraps a frozen
  mixture.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ccm.learn.mixtures import _gmr_kernels as _g
from ccm.learn.mixtures import _igmm_layout as _lay

__all__ = ["GMRConditional", "gmr_predict"]


# ---------------------------------------------------------------------------------------------
# validation helpers (shared with ccm.learn.mixtures.igmm)
# ---------------------------------------------------------------------------------------------


def check_split(in_idx: Any, out_idx: Any, n_features: int) -> tuple[np.ndarray, np.ndarray]:
    """Validate a split of the feature dimensions into conditioning inputs and outputs.

    Args:
        in_idx: Indices of the dimensions that are given (``x_in``), in the order of ``x_in``.
        out_idx: Indices of the dimensions to predict, in the order of the output.
        n_features: Dimension of the mixture.

    Returns:
        ``(in_idx, out_idx)`` as contiguous int64 arrays.

    Raises:
        ValueError: empty, out of range, repeated or overlapping indices.
    """
    out = []
    for name, idx in (("in_idx", in_idx), ("out_idx", out_idx)):
        try:
            arr = np.asarray(idx)
        except (TypeError, ValueError):
            raise ValueError(f"{name}: must be a sequence of integers, got {idx!r}") from None
        if arr.ndim == 0:
            arr = arr.reshape(1)
        if arr.ndim != 1 or arr.size == 0:
            raise ValueError(f"{name}: must be a non-empty 1-D sequence of integers, got {idx!r}")
        if arr.dtype.kind not in "iu":
            raise ValueError(f"{name}: must contain integers, got {idx!r}")
        if arr.min() < 0 or arr.max() >= n_features:
            raise ValueError(f"{name}: indices must lie in [0, {n_features - 1}], got {idx!r}")
        if np.unique(arr).size != arr.size:
            raise ValueError(f"{name}: repeated index in {idx!r}")
        out.append(np.ascontiguousarray(arr, dtype=np.int64))
    if np.intersect1d(out[0], out[1]).size:
        raise ValueError(f"in_idx and out_idx overlap: {in_idx!r} / {out_idx!r}")
    return out[0], out[1]


def as_rows(x: Any, n_cols: int, name: str) -> tuple[np.ndarray, bool]:
    """``x`` as a C-contiguous writable float64 (N, n_cols) array; flags a single row.

    Finiteness is checked by the kernels (cheaper than ``np.isfinite`` per step).

    Raises:
        ValueError: ``x`` is not numeric or has the wrong shape.
    """
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: must be numeric, got {type(x).__name__}") from None
    if arr.ndim == 1:
        if arr.shape[0] != n_cols:
            raise ValueError(
                f"{name}: expected shape ({n_cols},) or (N, {n_cols}), got {arr.shape}"
            )
        single = True
        arr = arr.reshape(1, n_cols)
    elif arr.ndim == 2:
        if arr.shape[1] != n_cols:
            raise ValueError(
                f"{name}: expected shape ({n_cols},) or (N, {n_cols}), got {arr.shape}"
            )
        single = False
    else:
        raise ValueError(f"{name}: expected shape ({n_cols},) or (N, {n_cols}), got {arr.shape}")
    if not (arr.flags.c_contiguous and arr.flags.writeable):
        arr = arr.copy()  # one numba specialisation only (C layout, writable)
    return arr, single


def check_mixture(
    weights: Any, means: Any, covariances: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validate full-covariance mixture parameters; returns float64 copies.

    Raises:
        ValueError: inconsistent shapes, non-finite values, negative or all-zero weights.
    """
    try:
        w = np.array(weights, dtype=np.float64)
        mu = np.array(means, dtype=np.float64)
        cov = np.array(covariances, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError("weights, means and covariances must be numeric arrays") from None
    if mu.ndim != 2 or mu.shape[0] == 0:
        raise ValueError(f"means: expected shape (K, d) with K >= 1, got {mu.shape}")
    n, d = mu.shape
    if w.shape != (n,):
        raise ValueError(f"weights: expected shape ({n},), got {w.shape}")
    if cov.shape != (n, d, d):
        raise ValueError(
            f"covariances: expected shape ({n}, {d}, {d}) (full covariances), got {cov.shape}"
        )
    for name, arr in (("weights", w), ("means", mu), ("covariances", cov)):
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name}: must be finite")
    if np.any(w < 0.0) or not w.sum() > 0.0:
        raise ValueError("weights: must be >= 0 with a positive sum")
    return w, mu, cov


# ---------------------------------------------------------------------------------------------
# plain numpy GMR
# ---------------------------------------------------------------------------------------------


def gmr_predict(
    weights: Any,
    means: Any,
    covariances: Any,
    x_in: Any,
    in_idx: Sequence[int] | np.ndarray,
    out_idx: Sequence[int] | np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """GMR conditional mean and covariance of ``x_out`` given ``x_in`` (seed A Eq. 6).

    Pure numpy and stateless: everything is refactorised on each call (fine for batches and
    tests; for a per-step loop use :class:`GMRConditional`).

    Args:
        weights: Mixture weights p(k), shape (K,) (need not be normalised).
        means: Component means, shape (K, d).
        covariances: Full component covariances, shape (K, d, d).
        x_in: One input (len(in_idx),) or a batch (N, len(in_idx)).
        in_idx: Dimensions given, in the order of ``x_in``.
        out_idx: Dimensions to predict, in output order.

    Returns:
        ``(mean, cov)`` with shapes (n_out,) and (n_out, n_out) for one input, or (N, n_out)
        and (N, n_out, n_out) for a batch.

    Raises:
        ValueError: bad shapes, non-finite values, or a component whose input block is not
            positive definite.
    """
    w, mu, cov = check_mixture(weights, means, covariances)
    ii, oo = check_split(in_idx, out_idx, mu.shape[1])
    X, single = as_rows(x_in, ii.size, "x_in")
    if not np.all(np.isfinite(X)):
        raise ValueError("x_in: must be finite")
    s_ii = cov[:, ii][:, :, ii]
    s_io = cov[:, ii][:, :, oo]
    s_oo = cov[:, oo][:, :, oo]
    try:
        chol = np.linalg.cholesky(s_ii)
    except np.linalg.LinAlgError:
        raise ValueError(
            "covariances: an input block Sigma_in,in is not positive definite"
        ) from None
    reg = np.swapaxes(np.linalg.solve(s_ii, s_io), 1, 2)  # (K, n_out, n_in)
    cond = s_oo - reg @ s_io
    cond = 0.5 * (cond + np.swapaxes(cond, 1, 2))
    logdet = 2.0 * np.log(np.diagonal(chol, axis1=1, axis2=2)).sum(axis=1)
    diff = X[:, None, :] - mu[None, :, ii]  # (N, K, n_in)
    z = np.linalg.solve(chol[None], diff[..., None])[..., 0]
    with np.errstate(divide="ignore"):
        logh = np.log(w)[None] - 0.5 * logdet[None] - 0.5 * np.sum(z * z, axis=-1)
    logh -= logh.max(axis=1, keepdims=True)
    h = np.exp(logh)
    h /= h.sum(axis=1, keepdims=True)
    m = mu[None, :, oo] + np.einsum("koi,nki->nko", reg, diff)
    mean = np.einsum("nk,nko->no", h, m)
    dm = m - mean[:, None, :]
    out_cov = np.einsum("nk,kab->nab", h, cond) + np.einsum("nk,nka,nkb->nab", h, dm, dm)
    if single:
        return mean[0], out_cov[0]
    return mean, out_cov


# ---------------------------------------------------------------------------------------------
# cached, numba-backed GMR
# ---------------------------------------------------------------------------------------------


class GMRConditional:
    """Cached GMR p(x_out | x_in) of a Gaussian mixture (Sung 2004; seed A Eq. 6).

    Per mixture component it caches the Cholesky factor and log-determinant of
    Sigma_in,in, the regression matrix Sigma_out,in Sigma_in,in^-1 and the conditional
    covariance, so that a prediction costs O(K d^2) in a numba kernel. Bound to an
    :class:`~ccm.learn.mixtures.igmm.IGMM` (via ``IGMM.conditional``) the cache follows the model:
    after a change, the factors of exactly those components whose mean, covariance or
    support changed are recomputed on the next prediction.

    Built directly it wraps a frozen mixture, e.g. a fitted scikit-learn ``GaussianMixture``::

        cond = GMRConditional(gm.weights_, gm.means_, gm.covariances_, [0, 1, 2, 3], [4, 5])
        f_next = cond.predict(s_t)

    Args:
        weights: Mixture weights, shape (K,).
        means: Component means, shape (K, d).
        covariances: Full component covariances, shape (K, d, d).
        in_idx: Dimensions given, in the order of ``x_in``.
        out_idx: Dimensions to predict, in output order.

    Raises:
        ValueError: bad mixture parameters or split, or an input block that is not positive
            definite.
    """

    def __init__(
        self,
        weights: Any,
        means: Any,
        covariances: Any,
        in_idx: Sequence[int] | np.ndarray,
        out_idx: Sequence[int] | np.ndarray,
    ) -> None:
        w, mu, cov = check_mixture(weights, means, covariances)
        n = mu.shape[0]
        comp = np.zeros((_lay.N_COMP, n))
        comp[_lay.C_SP] = w
        comp[_lay.C_AGE] = 1.0
        comp[_lay.C_STAMP] = np.arange(1, n + 1)
        istate = np.zeros(_lay.N_ISTATE, dtype=np.int64)
        istate[_lay.I_K] = n
        istate[_lay.I_STAMP] = n
        self._setup(in_idx, out_idx, mu, cov, comp, istate)
        self.predict(mu[0, self._in_idx])  # factorise now: fail early on a singular block

    @classmethod
    def _bound(
        cls,
        in_idx: np.ndarray,
        out_idx: np.ndarray,
        means: np.ndarray,
        covs: np.ndarray,
        comp: np.ndarray,
        istate: np.ndarray,
    ) -> GMRConditional:
        """A conditional reading live (preallocated) model buffers; used by IGMM."""
        obj = cls.__new__(cls)
        obj._setup(in_idx, out_idx, means, covs, comp, istate)
        return obj

    def _setup(
        self,
        in_idx: Any,
        out_idx: Any,
        means: np.ndarray,
        covs: np.ndarray,
        comp: np.ndarray,
        istate: np.ndarray,
    ) -> None:
        kmax, d = means.shape
        ii, oo = check_split(in_idx, out_idx, d)
        di, do = ii.size, oo.size
        self._in_idx, self._out_idx = ii, oo
        self._di, self._do = di, do
        self._split = np.concatenate([[di, do], ii, oo]).astype(np.int64)
        self._means, self._covs, self._comp, self._istate = means, covs, comp, istate
        self._cache = _g.new_gmr_cache(kmax, di, do)
        self._no_cov = np.zeros((1, do, do))

    def _owned_nbytes(self) -> int:
        """Bytes of the arrays this object owns (not the mixture buffers it may share)."""
        own = (self._in_idx, self._out_idx, self._split, self._cache, self._no_cov)
        return int(sum(a.nbytes for a in own))

    @property
    def in_idx(self) -> np.ndarray:
        """Indices of the conditioning dimensions (order of ``x_in``)."""
        return self._in_idx.copy()

    @property
    def out_idx(self) -> np.ndarray:
        """Indices of the predicted dimensions (output order)."""
        return self._out_idx.copy()

    def _run(self, x_in: Any, want_cov: bool) -> tuple[np.ndarray, np.ndarray | None, bool]:
        X, single = as_rows(x_in, self._di, "x_in")
        mean = np.empty((X.shape[0], self._do))
        cov = np.empty((X.shape[0], self._do, self._do)) if want_cov else self._no_cov
        status = _g.gmr_rows(
            X, self._split, self._means, self._covs, self._comp, self._istate, self._cache,
            mean, cov, want_cov,
        )  # fmt: skip
        if status != 0:
            self.raise_status(status)
        return mean, (cov if want_cov else None), single

    @staticmethod
    def raise_status(status: int) -> None:
        """Raise the ValueError for a non-zero :func:`~ccm.learn.mixtures._gmr_kernels.gmr_rows`
        status."""
        if status == -1:
            raise ValueError("the mixture has no components yet: call partial_fit first")
        if status <= -10:
            raise ValueError(f"x_in: row {-status - 10} is not finite")
        raise ValueError(
            f"covariances: component {-status - 2} has an input block Sigma_in,in that is "
            "not positive definite"
        )

    def predict(self, x_in: Any) -> np.ndarray:
        """Conditional mean E[x_out | x_in] (seed A Eq. 6).

        Args:
            x_in: One input (n_in,) or a batch (N, n_in).

        Returns:
            Shape (n_out,) for one input, (N, n_out) for a batch.
        """
        mean, _, single = self._run(x_in, False)
        return mean[0] if single else mean

    def kernel_buffers(self) -> tuple[np.ndarray, ...]:
        """The arguments :func:`ccm.learn.mixtures._gmr_kernels.gmr_rows` takes between the rows
        and
        the output (split, mixture buffers, cache), for a control loop that calls it itself."""
        return self._split, self._means, self._covs, self._comp, self._istate, self._cache

    def predict_cov(self, x_in: Any) -> tuple[np.ndarray, np.ndarray]:
        """Conditional mean and covariance of x_out given x_in.

        The covariance is that of the conditional mixture collapsed to one Gaussian: the
        weighted conditional covariances plus the spread of the conditional means.

        Args:
            x_in: One input (n_in,) or a batch (N, n_in).

        Returns:
            ``(mean, cov)``: (n_out,), (n_out, n_out) for one input; (N, n_out),
            (N, n_out, n_out) for a batch.
        """
        mean, cov, single = self._run(x_in, True)
        assert cov is not None
        return (mean[0], cov[0]) if single else (mean, cov)
