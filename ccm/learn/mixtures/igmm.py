"""Incremental Gaussian mixture model (IGMM; Engel & Heinen 2010) and its GMR forward model.

Seed A (Sidhik et al.) §3.1 learns, per contact mode, a forward model from points
X_t = [S_{t-1}, D_t] (Eq. 2, 3) with an incrementally updated GMM that maximises the
likelihood of Eq. 5, and predicts D_{t+1} from S_t by Gaussian mixture regression (Eq. 6).

Algorithm (one point x, Engel & Heinen 2010, "Incremental learning of multivariate Gaussian
mixture models"):

1. For every component j compute the squared Mahalanobis distance
   d_j^2 = (x - mu_j)^T C_j^-1 (x - mu_j) and the posterior
   p(j|x) = p(x|j) p(j) / sum_q p(x|q) p(q) (densities from log det C_j via Cholesky).
2. Novelty: x is novel if d_j^2 >= chi2_{n_features}(novelty_chi2_quantile) for every j.
   Engel & Heinen state the test as p(x|j) < tau_nov / ((2 pi)^{D/2} sqrt|C_j|) for all j, a
   fraction tau_nov of each component's peak density; that is the same as
   d_j^2 > -2 ln tau_nov. We parametrise the same test by a chi-square quantile because it
   means the same thing in any dimension: with the default 0.99, a point drawn from a
   component is taken for novel with probability 1 %. The equivalent tau_nov is exposed as
   ``novelty_tau_``.
3. Novel: create mu = x, C = diag(sigma_init^2), v = 1, sp = 1. If that would exceed
   ``max_components``, first merge the two closest components by moment matching
   (``overflow="merge"``, closeness = Runnalls' KL upper bound) or drop the least supported
   one (``overflow="prune"``).
4. Otherwise, for every component: v_j += 1, sp_j += p(j|x), w_j = p(j|x) / sp_j,
   e = x - mu_j (old mean), mu_j += w_j e and
   C_j <- (1 - w_j) C_j + w_j (1 - w_j) e e^T + w_j * cov_floor * I.
   The first two terms are the exact weighted-moment update; the version often quoted,
   (1 - w) C + w e* e*^T - dmu dmu^T, loses positive definiteness on real data
   within a dozen points when a point lies > 2 sigma from a young component (w ~ 0.5;
   ``tests/test_igmm.py``). The last term is the covariance floor: by induction every
   eigenvalue of C_j stays >= cov_floor (it is the moment update of points blurred by
   N(0, cov_floor I), like scikit-learn's ``reg_covar``), so no eigen-decomposition is needed
   per step.
   Then components with v_j > v_min and sp_j < sp_min are removed (never the last one).
5. Priors p(j) = sp_j / sum_q sp_q.

All state lives in arrays preallocated for ``max_components``: per-step cost and memory are
flat over arbitrarily long streams (:mod:`ccm.learn.mixtures.igmm_buffers` reads the fitted
attributes from them). The numeric work is done by numba kernels
(:mod:`ccm.learn.mixtures._igmm_kernels`); the settings are checked with
:mod:`ccm.learn.mixtures.igmm_settings`.

Behaviour worth knowing on long streams: a component's learning rate w_j ~ 1 / sp_j decays
like 1/n (the model is a running average, not a tracker), and the prior p(j) grows with sp_j.
At 1 kHz a component owns thousands of points within seconds; when the data drift, a new
component created at the edge gets a tiny posterior next to it, fails the support test
and is removed. On a drifting stream the model can therefore settle on very few components
that no longer move. That is the algorithm as published (seed A uses it per contact mode,
over one task); a forgetting factor would be an extension.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ccm.core.errors import (
    ConfigError,
    check_choice,
    check_int_positive,
    check_nonneg,
    check_positive,
    check_range,
)
from ccm.learn.mixtures import _igmm_kernels as _k
from ccm.learn.mixtures import _igmm_layout as _lay
from ccm.learn.mixtures import igmm_io
from ccm.learn.mixtures.gmr import GMRConditional, as_rows, check_split
from ccm.learn.mixtures.igmm_buffers import MixtureBuffers
from ccm.learn.mixtures.igmm_settings import check_sigma, chi2_quantile

__all__ = ["IGMM"]

_MAX_CACHED_SPLITS = 16


class IGMM(MixtureBuffers):
    """Incremental Gaussian mixture model (Engel & Heinen 2010) with GMR (seed A Eq. 5, 6).

    Example (seed A's AVIC forward model, d = 6: four inputs S_{t-1}, two outputs D_t)::

        model = IGMM(6, sigma_init=[0.02, 0.02, 1.0, 0.1, 1.0, 0.1])
        fm = model.conditional(in_idx=[0, 1, 2, 3], out_idx=[4, 5])
        for each control step:
            model.partial_fit(np.r_[s_prev, d_now])   # X_t = [S_{t-1}, D_t]
            d_next = fm.predict(s_now)                # f_fm: S_t -> D_{t+1}

    Args:
        n_features: Dimension d of the points.
        novelty_chi2_quantile: A point is novel (creates a component) when its squared
            Mahalanobis distance to every component is at least this quantile of the
            chi-square distribution with d degrees of freedom. In (0, 1); default 0.99
            (equivalent tau_nov = exp(-chi2 / 2) of Engel & Heinen 2010).
        sigma_init: Standard deviation(s) of a new component, a scalar or one per feature,
            in data units (Engel & Heinen use a fraction of the data's spread). The default
            0.1 (chosen) suits features scaled to order one, as
            :mod:`ccm.learn.mixtures.forward_model` does; pass per-feature values for raw SI data.
        v_min: Age (updates since creation) after which a component must have support.
        sp_min: Minimum accumulated posterior support of a component older than ``v_min``;
            younger-but-unsupported components are removed (0 disables removal).
        max_components: Hard bound on the number of components.
        cov_floor: Lower bound on every covariance eigenvalue (data units squared).
        overflow: What makes room for a new component when ``max_components`` are in use:
            ``"merge"`` the two closest (moment matching) or ``"prune"`` the least supported.
        key: Configuration key used in error messages (``f"{key}.<arg>"``).

    Attributes:
        n_components_: Number of live components K.
        weights_: Priors p(j) = sp_j / sum sp, shape (K,).
        means_: Shape (K, d).
        covariances_: Shape (K, d, d).
        n_seen_: Number of points processed.

    Raises:
        ConfigError: an argument is out of range (the message names ``key.<arg>``).
    """

    def __init__(
        self,
        n_features: int,
        *,
        novelty_chi2_quantile: float = 0.99,
        sigma_init: float | Sequence[float] | np.ndarray = 0.1,
        v_min: int = 5,
        sp_min: float = 3.0,
        max_components: int = 20,
        cov_floor: float = 1e-6,
        overflow: str = "merge",
        key: str = "igmm",
    ) -> None:
        if not isinstance(key, str):
            raise ConfigError("igmm.key", f"must be a string, got {key!r}")
        d = check_int_positive(f"{key}.n_features", n_features)
        q = check_range(f"{key}.novelty_chi2_quantile", novelty_chi2_quantile, 0.0, 1.0)
        if not 0.0 < q < 1.0:
            raise ConfigError(
                f"{key}.novelty_chi2_quantile", f"must be in (0, 1) exclusive, got {q!r}"
            )
        sig = check_sigma(f"{key}.sigma_init", sigma_init, d)
        v_min = check_int_positive(f"{key}.v_min", v_min)
        sp_min = check_nonneg(f"{key}.sp_min", sp_min)
        kmax = check_int_positive(f"{key}.max_components", max_components)
        if kmax < 2 and overflow == "merge":
            raise ConfigError(
                f"{key}.max_components", "must be >= 2 with overflow='merge' (a merge needs two)"
            )
        floor = check_positive(f"{key}.cov_floor", cov_floor)
        overflow = check_choice(f"{key}.overflow", overflow, ("merge", "prune"))
        if np.min(sig) ** 2 < floor:
            raise ConfigError(
                f"{key}.sigma_init",
                f"sigma_init**2 must be >= cov_floor={floor!r}, got min sigma_init "
                f"{float(np.min(sig))!r}",
            )

        self.n_features = d
        self.novelty_chi2_quantile = q
        self.sigma_init = sig
        self.v_min = v_min
        self.sp_min = sp_min
        self.max_components = kmax
        self.cov_floor = floor
        self.overflow = overflow
        self.key = key
        self._allocate()

    def _allocate(self) -> None:
        """The kernels' settings vector and the mixture buffers (:mod:`._igmm_layout`)."""
        d, kmax, floor = self.n_features, self.max_components, self.cov_floor
        sp_min, v_min, overflow, sig = self.sp_min, self.v_min, self.overflow, self.sigma_init
        self._threshold = chi2_quantile(self.novelty_chi2_quantile, d)
        self._params = np.zeros(_lay.N_PARAMS)
        self._params[_lay.P_THRESHOLD] = self._threshold
        self._params[_lay.P_FLOOR] = floor
        self._params[_lay.P_SP_MIN] = sp_min
        self._params[_lay.P_V_MIN] = float(v_min)
        self._params[_lay.P_OVERFLOW] = (
            _lay.OVERFLOW_MERGE if overflow == "merge" else _lay.OVERFLOW_PRUNE
        )
        self._sigma2 = np.ascontiguousarray(sig**2)
        self._means = np.zeros((kmax, d))
        self._covs = np.zeros((kmax, d, d))
        self._chols = np.zeros((kmax, d, d))
        self._comp = np.zeros((_lay.N_COMP, kmax))
        self._sp = self._comp[_lay.C_SP]  # views
        self._age = self._comp[_lay.C_AGE]
        self._istate = np.zeros(_lay.N_ISTATE, dtype=np.int64)
        self._work = np.zeros(2 * d + kmax + 2 * d * d)
        self._splits: dict[tuple[tuple[int, ...], tuple[int, ...]], GMRConditional] = {}

    # -----------------------------------------------------------------------------------------
    # settings and size (the fitted attributes: ccm.learn.mixtures.igmm_buffers)
    # -----------------------------------------------------------------------------------------

    def get_params(self) -> dict[str, Any]:
        """Constructor arguments (JSON-safe)."""
        return {
            "n_features": self.n_features,
            "novelty_chi2_quantile": self.novelty_chi2_quantile,
            "sigma_init": self.sigma_init.tolist(),
            "v_min": self.v_min,
            "sp_min": self.sp_min,
            "max_components": self.max_components,
            "cov_floor": self.cov_floor,
            "overflow": self.overflow,
        }

    def nbytes(self) -> int:
        """Bytes held by the model's arrays, including cached GMR splits (flat over time)."""
        total = sum(
            a.nbytes
            for a in (
                self._means,
                self._covs,
                self._chols,
                self._comp,
                self._istate,
                self._work,
                self._params,
                self._sigma2,
            )
        )
        for cond in self._splits.values():
            total += cond._owned_nbytes()
        return int(total)

    # -----------------------------------------------------------------------------------------
    # learning
    # -----------------------------------------------------------------------------------------

    def partial_fit(self, X: Any) -> IGMM:
        """Learn from one point (d,) or a batch (N, d), processed in order (Engel & Heinen).

        Args:
            X: Point(s) X_t = [S_{t-1}, D_t] (seed A Eq. 2, 3) or any d-dimensional data.

        Returns:
            ``self``.

        Raises:
            ValueError: wrong shape or a non-finite value (the model is left unchanged).
        """
        rows, _ = as_rows(X, self.n_features, "X")
        status = _k.fit_rows(
            rows,
            self._means,
            self._covs,
            self._chols,
            self._comp,
            self._istate,
            self._params,
            self._sigma2,
            self._work,
        )
        if status:
            raise ValueError(f"X: row {-status - 1} is not finite; the model was not changed")
        return self

    def fit(self, X: Any) -> IGMM:
        """:meth:`reset`, then :meth:`partial_fit` on the rows of ``X`` in order."""
        rows, _ = as_rows(X, self.n_features, "X")
        if not np.all(np.isfinite(rows)):
            raise ValueError("X: must be finite; the model was not changed")
        return self.reset().partial_fit(rows)

    # -----------------------------------------------------------------------------------------
    # densities and regression
    # -----------------------------------------------------------------------------------------

    def _require_components(self) -> int:
        n = self.n_components_
        if n == 0:
            raise ValueError("IGMM has no components yet: call partial_fit first")
        return n

    def score_samples(self, X: Any) -> np.ndarray:
        """Log density log p(x) = log sum_j p(j) N(x | mu_j, C_j) per row (seed A Eq. 5).

        Args:
            X: One point (d,) or a batch (N, d).

        Returns:
            Shape (N,) (a length-1 array for one point).
        """
        n = self._require_components()
        rows, _ = as_rows(X, self.n_features, "X")
        if not np.all(np.isfinite(rows)):
            raise ValueError("X: must be finite")
        out = np.empty(rows.shape[0])
        work = np.empty(2 * self.n_features + n)
        _k.score_rows(rows, n, self._means, self._chols, self._comp, work, out)
        return out

    def score(self, X: Any) -> float:
        """Mean log-likelihood of the rows of ``X``."""
        return float(np.mean(self.score_samples(X)))

    def conditional(
        self, in_idx: Sequence[int] | np.ndarray, out_idx: Sequence[int] | np.ndarray
    ) -> GMRConditional:
        """GMR view p(x_out | x_in) of this model (seed A Eq. 6), refreshed on model changes.

        Hold on to the returned object in a control loop: its :meth:`~GMRConditional.predict`
        skips the split lookup. The same object is returned for the same split.

        Args:
            in_idx: Conditioning dimensions, in the order of ``x_in``.
            out_idx: Predicted dimensions, in output order.
        """
        try:  # fast path: a split seen before (the dict holds validated splits only)
            cond = self._splits.get((tuple(in_idx), tuple(out_idx)))
        except TypeError:
            cond = None
        if cond is not None:
            return cond
        ii, oo = check_split(in_idx, out_idx, self.n_features)
        key = (tuple(ii.tolist()), tuple(oo.tolist()))
        cond = self._splits.get(key)
        if cond is None:
            if len(self._splits) >= _MAX_CACHED_SPLITS:
                self._splits.pop(next(iter(self._splits)))
            cond = GMRConditional._bound(ii, oo, self._means, self._covs, self._comp, self._istate)
            self._splits[key] = cond
        return cond

    def predict(
        self,
        x_in: Any,
        in_idx: Sequence[int] | np.ndarray,
        out_idx: Sequence[int] | np.ndarray,
    ) -> np.ndarray:
        """GMR conditional mean E[x_out | x_in] (Sung 2004; seed A Eq. 6).

        Args:
            x_in: One input (len(in_idx),) or a batch (N, len(in_idx)).
            in_idx: Conditioning dimensions, in the order of ``x_in``.
            out_idx: Predicted dimensions, in output order.

        Returns:
            Shape (len(out_idx),) or (N, len(out_idx)).
        """
        self._require_components()
        return self.conditional(in_idx, out_idx).predict(x_in)

    def predict_cov(
        self,
        x_in: Any,
        in_idx: Sequence[int] | np.ndarray,
        out_idx: Sequence[int] | np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """GMR conditional mean and covariance of x_out given x_in.

        The covariance is the mixture of the component conditional covariances plus the
        spread of the component conditional means around the GMR mean.

        Returns:
            ``(mean, cov)``: (n_out,), (n_out, n_out) for one input; (N, n_out),
            (N, n_out, n_out) for a batch.
        """
        self._require_components()
        return self.conditional(in_idx, out_idx).predict_cov(x_in)

    # -----------------------------------------------------------------------------------------
    # persistence (no pickle)
    # -----------------------------------------------------------------------------------------

    def state_dict(self) -> dict[str, Any]:
        """JSON-safe snapshot (settings, components, counters); see :meth:`from_state_dict`
        (:mod:`ccm.learn.mixtures.igmm_io`)."""
        return igmm_io.to_state(self)

    @classmethod
    def from_state_dict(cls, data: Mapping[str, Any], *, key: str = "igmm") -> IGMM:
        """Rebuild a model from :meth:`state_dict` output.

        Raises:
            ValueError: wrong format, inconsistent shapes, non-finite values, covariances
                that are not positive definite (ConfigError for bad settings).
        """
        return igmm_io.from_state(cls, data, key)

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the model to ``path`` as an uncompressed NPZ (no pickled objects), atomically;
        returns the path written."""
        return igmm_io.save_npz(self, path)

    @classmethod
    def load(cls, path: str | os.PathLike[str], *, key: str = "igmm") -> IGMM:
        """Read a model written by :meth:`save` (ValueError for a missing piece, a corrupted
        file or one that is not an IGMM file)."""
        return igmm_io.load_npz(cls, path, key)
