"""GP force-over-pose models of Haninger et al. (seed B, §3.1.1, Eq. 1-3).

One GP per force dimension, ``f(x) ~ GP(m(x), k(x, x'))``, fitted independently, so the
force covariance is diagonal (seed B). The posterior mean, its variance and the gradient of
the mean w.r.t. pose are available in numpy and as casadi functions for an optimiser. This
module holds one output dimension (:class:`GPForceModel`); the stack over the force dimensions
is :class:`ccm.learn.gp.gp_force_models.GPForceModels`.

Deviations from / readings of the printed formulas (documented choices):

* Eq. 1 writes the kernel amplitude as ``σ_n²`` and calls it the noise variance, and Eq. 2
  adds the same ``σ_n²`` to the training covariance: one hyperparameter is both the kernel
  amplitude and the noise. ``variance="tied"`` is that model as printed:
  ``k(x, x') = σ_n² exp(-½ (x-x')ᵀ diag(l⁻²) (x-x'))``, ``K + σ_n² I`` and
  ``Σ^f = σ_n² - k*ᵀ(K+σ_n²I)⁻¹k*``, which reverts to ``σ_n²`` far from the data (seed B
  §4.3.1: "the GP will revert to a baseline variance given by hyperparameter σ_n²") and stays
  of the order of the data's scatter near it. ``variance="separate"`` is the textbook form
  with a *signal* variance ``σ_f²`` and a separate *noise* variance ``σ_n²``; its ``Σ^f`` is
  the latent variance ``σ_f² - k*ᵀ(K+σ_n²I)⁻¹k*``, which the fitted noise can make tiny where
  the data scatter (the scatter goes to ``σ_n²``, which ``Σ^f`` does not contain).
* Eq. 3 as printed (``c1`` if ``x <= c3``, else ``c1 + c2 x``) is discontinuous at ``c3``.
  ``hinge_form="continuous"`` (default) uses ``m = c1 + c2 max(0, x - c3)``;
  ``hinge_form="paper"`` uses the printed formula. In the paper form the NLL is piecewise
  constant in ``c3`` (zero gradient), so ``c3`` is not moved by L-BFGS-B: it is chosen by the
  least-squares grid initialisation and the random restarts, and the best NLL wins.
* ``hinge_form="smooth"`` replaces ``max(0, z)`` by the softplus ``w log(1 + exp(z / w))``
  (``w = hinge_width``, metres), a ccm option for the MPC: with the kinked hinge the GP mean's
  slope, and with it the well-damped constraint's stiffness estimate (Eq. 19), jumps from 0 to
  c2 at c3, and IPOPT stalls on that kink (seed B §6.1 reports more infeasible solves with the
  hinge). The softplus spreads the jump over a few ``w``.
* ``x`` in Eq. 3 is element ``hinge_input`` of the pose. At the kink, derivatives of the mean
  are right derivatives (slope ``c2``) in numpy; casadi's ``fmax``/``if_else`` derivative at
  exactly the kink may differ.

Hyperparameters (log length scales, log σ_f², log σ_n², one variance when tied, and the hinge
c1, c2, c3) are fitted jointly by minimising the negative log-likelihood with scipy L-BFGS-B
and analytic gradients; c3 is bounded to the data range of ``x[:, hinge_input]``. Casadi
functions use ``MX`` with the training data, ``alpha`` and ``L⁻¹`` embedded as ``DM``
constants (dense products stay single nodes, which keeps graphs small for hundreds of points).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import casadi as ca
import numpy as np
import scipy.linalg
import scipy.optimize
import scipy.special

from ccm.core.errors import (
    ConfigError,
    check_bounds,
    check_choice,
    check_int_nonneg,
    check_positive,
)

_LOG2PI = float(np.log(2.0 * np.pi))


def _as_array(key: str, value: Any, ndim: int) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(key, "must be a numeric array") from None
    if arr.ndim != ndim or arr.size == 0:
        raise ConfigError(key, f"must be a non-empty {ndim}-D array, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ConfigError(key, "must be finite (found NaN or inf)")
    return arr


class GPForceModel:
    """One output dimension: f(x) ~ GP(m(x), k(x, x')) with SE-ARD kernel, zero or hinge mean.

    Args:
        mean: ``"zero"`` or ``"hinge"`` (Eq. 3, seed B).
        hinge_form: ``"continuous"`` (``c1 + c2 max(0, x - c3)``), ``"smooth"`` (softplus of
            width ``hinge_width``) or ``"paper"`` (Eq. 3 as printed).
        hinge_width: softplus width w [m] of the smooth form.
        hinge_input: index of the pose element the hinge acts on.
        length_scale_bounds: bounds on each ARD length scale (Eq. 1).
        signal_var_bounds: bounds on σ_f² (unused when tied).
        noise_var_bounds: bounds on σ_n² (the one variance when tied).
        variance: ``"separate"`` (σ_f² and σ_n²) or ``"tied"`` (Eq. 1-2 as printed: one
            σ_n² is the kernel amplitude and the noise; module docstring).
        n_restarts: extra seeded random starts of the NLL optimiser.
        seed: seed of the random starts.
        key: configuration-key prefix for errors.
    """

    def __init__(
        self,
        *,
        mean: str = "zero",
        hinge_form: str = "continuous",
        hinge_width: float = 2e-4,
        hinge_input: int = 0,
        length_scale_bounds: Sequence[float] = (1e-3, 1e2),
        signal_var_bounds: Sequence[float] = (1e-4, 1e4),
        noise_var_bounds: Sequence[float] = (1e-6, 1e2),
        variance: str = "separate",
        n_restarts: int = 2,
        seed: int = 0,
        key: str = "gp",
    ) -> None:
        self.key = key
        self.mean = check_choice(f"{key}.mean", mean, ("zero", "hinge"))
        self.hinge_form = check_choice(
            f"{key}.hinge_form", hinge_form, ("continuous", "smooth", "paper")
        )
        self.hinge_width = check_positive(f"{key}.hinge_width", hinge_width)
        self.hinge_input = check_int_nonneg(f"{key}.hinge_input", hinge_input)
        self.length_scale_bounds = check_bounds(f"{key}.length_scale_bounds", length_scale_bounds)
        self.signal_var_bounds = check_bounds(f"{key}.signal_var_bounds", signal_var_bounds)
        self.noise_var_bounds = check_bounds(f"{key}.noise_var_bounds", noise_var_bounds)
        self.variance = check_choice(f"{key}.variance", variance, ("separate", "tied"))
        self.n_restarts = check_int_nonneg(f"{key}.n_restarts", n_restarts)
        self.seed = check_int_nonneg(f"{key}.seed", seed)
        self.hinge_: tuple[float, float, float] | None = None

    # ----------------------------------------------------------------- mean function (Eq. 3)
    def _hinge_parts(self, x: np.ndarray, c3: float) -> tuple[np.ndarray, np.ndarray]:
        """Return (feature multiplying c2, indicator of the sloped side, right-continuous)."""
        if self.hinge_form == "continuous":
            return np.maximum(0.0, x - c3), (x >= c3).astype(float)
        if self.hinge_form == "smooth":
            z = (x - c3) / self.hinge_width
            return self.hinge_width * np.logaddexp(0.0, z), scipy.special.expit(z)
        return np.where(x > c3, x, 0.0), (x >= c3).astype(float)

    def _mean_fn(self, X: np.ndarray, hinge: tuple[float, float, float] | None) -> np.ndarray:
        if hinge is None:
            return np.zeros(X.shape[0])
        c1, c2, c3 = hinge
        return c1 + c2 * self._hinge_parts(X[:, self.hinge_input], c3)[0]

    def _lsq_hinge(self, x: np.ndarray, f: np.ndarray, c3: float) -> tuple[float, float]:
        A = np.column_stack([np.ones_like(x), self._hinge_parts(x, c3)[0]])
        coef = np.linalg.lstsq(A, f, rcond=None)[0]
        return float(coef[0]), float(coef[1])

    # ------------------------------------------------------------- negative log-likelihood
    def _unpack(self, p: np.ndarray) -> tuple[np.ndarray, float, float, Any]:
        d = self._d
        ls, sf2, sn2 = np.exp(p[:d]), float(np.exp(p[d])), float(np.exp(p[d + 1]))
        hinge = None
        if self.mean == "hinge":
            fs, xr, xmin = self._scales
            hinge = (fs * p[d + 2], fs / xr * p[d + 3], xmin + xr * p[d + 4])
        return ls, sf2, sn2, hinge

    def _full(self, q: np.ndarray) -> np.ndarray:
        """The optimiser's vector as the full [log l, log σ_f², log σ_n², hinge] vector: when
        tied, the one variance fills both slots (Eq. 1-2 as printed)."""
        if self.variance == "separate":
            return q
        d = self._d
        return np.concatenate([q[: d + 1], q[d : d + 1], q[d + 1 :]])

    def _objective(self, q: np.ndarray) -> tuple[float, np.ndarray]:
        """NLL and gradient over the optimiser's vector (tied: the two variance slots' gradients
        add, by the chain rule)."""
        nll, g = self._nll_and_grad(self._full(q))
        if self.variance == "separate":
            return nll, g
        d = self._d
        return nll, np.concatenate([g[:d], [g[d] + g[d + 1]], g[d + 2 :]])

    def _nll_and_grad(self, p: np.ndarray) -> tuple[float, np.ndarray]:
        d, M = self._d, self._X.shape[0]
        ls, sf2, sn2, hinge = self._unpack(p)
        scaled = self._sqd / (ls**2)[:, None, None]
        Kf = sf2 * np.exp(-0.5 * scaled.sum(axis=0))
        Ky = Kf + sn2 * np.eye(M)
        try:
            L = scipy.linalg.cholesky(Ky, lower=True)
        except np.linalg.LinAlgError:
            return 1e25, np.zeros_like(p)
        r = self._f - self._mean_fn(self._X, hinge)
        alpha = scipy.linalg.cho_solve((L, True), r)
        nll = 0.5 * r @ alpha + np.log(np.diag(L)).sum() + 0.5 * M * _LOG2PI
        W = scipy.linalg.cho_solve((L, True), np.eye(M)) - np.outer(alpha, alpha)
        g = np.zeros_like(p)
        WK = W * Kf
        g[:d] = 0.5 * np.einsum("ij,kij->k", WK, scaled)
        g[d] = 0.5 * WK.sum()
        g[d + 1] = 0.5 * sn2 * np.trace(W)
        if hinge is not None:
            fs, xr, _ = self._scales
            feat, ind = self._hinge_parts(self._X[:, self.hinge_input], hinge[2])
            g[d + 2] = -alpha.sum() * fs
            g[d + 3] = -(alpha @ feat) * fs / xr
            if self.hinge_form in ("continuous", "smooth"):
                g[d + 4] = (alpha @ ind) * hinge[1] * xr
        return float(nll), g

    def negative_log_likelihood(
        self,
        length_scales: Any,
        signal_var: float,
        noise_var: float,
        hinge: tuple[float, float, float] | None = None,
    ) -> float:
        """NLL of the fitted training data under the given hyperparameters (Eq. 1-3, seed B)."""
        self._check_fitted()
        fs, xr, xmin = self._scales
        p = [*np.log(np.asarray(length_scales, float)), np.log(signal_var), np.log(noise_var)]
        if self.mean == "hinge":
            if hinge is None:
                raise ConfigError(f"{self.key}.mean", "hinge mean needs hinge=(c1, c2, c3)")
            p += [hinge[0] / fs, hinge[1] * xr / fs, (hinge[2] - xmin) / xr]
        X = self._X
        self._sqd = (X[:, None, :] - X[None, :, :]).transpose(2, 0, 1) ** 2
        try:
            return self._nll_and_grad(np.asarray(p, dtype=float))[0]
        finally:
            del self._sqd

    # ------------------------------------------------------------------------------ fitting
    def fit(self, X: Any, f: Any) -> GPForceModel:
        """Fit hyperparameters by NLL minimisation and store ``alpha`` (Eq. 1-3, seed B).

        Args:
            X: poses, shape (M, d), M >= 2.
            f: one force component, shape (M,).

        Returns:
            self
        """
        k = self.key
        X = _as_array(f"{k}.X", X, 2)
        f = _as_array(f"{k}.f", f, 1)
        M, d = X.shape
        if M < 2:
            raise ConfigError(f"{k}.X", f"needs at least 2 samples, got {M}")
        if f.shape[0] != M:
            raise ConfigError(f"{k}.f", f"must have length {M} (rows of X), got {f.shape[0]}")
        if self.mean == "hinge" and self.hinge_input >= d:
            raise ConfigError(f"{k}.hinge_input", f"must be < input dimension {d}")
        self._X, self._f, self._d = X, f, d
        self._sqd = (X[:, None, :] - X[None, :, :]).transpose(2, 0, 1) ** 2
        rng = np.random.default_rng(self.seed)
        lb = [np.log(self.length_scale_bounds)] * d
        if self.variance == "separate":
            lb.append(np.log(self.signal_var_bounds))
        lb.append(np.log(self.noise_var_bounds))
        x_std = np.where(X.std(axis=0) > 0, X.std(axis=0), 1.0)
        xh = X[:, min(self.hinge_input, d - 1)]
        xr = float(xh.max() - xh.min()) or 1.0
        self._scales = (float(f.std()) or 1.0, xr, float(xh.min()))
        if self.mean == "hinge":
            lb += [(None, None), (None, None), (0.0, 1.0)]
        grid = np.linspace(0.0, 1.0, 21)
        starts = [self._start(x_std, xh, grid, None, rng)]
        starts += [self._start(x_std, xh, grid, rng.uniform(), rng) for _ in range(self.n_restarts)]
        if self.variance == "tied":  # one variance: the start's residual variance (index d)
            starts = [np.delete(s, d + 1) for s in starts]
        lo, hi = (
            np.array([np.inf * (2 * i - 1) if b[i] is None else b[i] for b in lb]) for i in (0, 1)
        )
        starts = [np.clip(s, lo, hi) for s in starts]
        self.initial_params_ = self._as_dict(self._full(starts[0]))
        best = None
        for s in starts:
            res = scipy.optimize.minimize(
                self._objective, s, jac=True, method="L-BFGS-B", bounds=lb
            )
            cand = min((res.fun, res.x), (self._objective(s)[0], s), key=lambda c: c[0])
            if best is None or cand[0] < best[0]:
                best = cand
        self.nll_, p = float(best[0]), self._full(best[1])
        pr = self._as_dict(p)
        self.length_scales_, self.signal_var_ = pr["length_scales"], pr["signal_var"]
        self.noise_var_, self.hinge_ = pr["noise_var"], pr["hinge"]
        Kf = self._kernel(X, X)
        L = scipy.linalg.cholesky(Kf + self.noise_var_ * np.eye(M), lower=True)
        self.alpha_ = scipy.linalg.cho_solve((L, True), f - self._mean_fn(X, self.hinge_))
        self.L_inv_ = scipy.linalg.solve_triangular(L, np.eye(M), lower=True)
        del self._sqd
        return self

    def _start(
        self, x_std: np.ndarray, xh: np.ndarray, grid: np.ndarray, u3: float | None, rng: Any
    ) -> np.ndarray:
        """Deterministic start (u3 None: LSQ hinge on a c3 grid) or a seeded random one."""
        f, d = self._f, self._d
        random = u3 is not None
        ls = np.log(x_std) + (rng.uniform(-1.5, 1.5, d) if random else 0.0)
        fs, xr, xmin = self._scales
        hinge_p: list[float] = []
        resid = f
        if self.mean == "hinge":
            if u3 is None:  # deterministic start: least-squares hinge over a grid of c3
                sse = []
                for u in grid:
                    c1, c2 = self._lsq_hinge(xh, f, xmin + xr * u)
                    sse.append(np.sum((f - c1 - c2 * self._hinge_parts(xh, xmin + xr * u)[0]) ** 2))
                u3 = float(grid[int(np.argmin(sse))])
            c1, c2 = self._lsq_hinge(xh, f, xmin + xr * u3)
            resid = f - c1 - c2 * self._hinge_parts(xh, xmin + xr * u3)[0]
            hinge_p = [c1 / fs, c2 * xr / fs, u3]
        var = max(float(resid.var()), 1e-12)
        sf2, sn2 = np.log(var), np.log(0.1 * var)
        if random:
            sf2, sn2 = sf2 + rng.uniform(-1.0, 1.0), sn2 + rng.uniform(-2.0, 1.0)
        return np.array([*ls, sf2, sn2, *hinge_p], dtype=float)

    def _as_dict(self, p: np.ndarray) -> dict[str, Any]:
        ls, sf2, sn2, hinge = self._unpack(p)
        hinge = None if hinge is None else tuple(float(c) for c in hinge)
        return {"length_scales": ls.copy(), "signal_var": sf2, "noise_var": sn2, "hinge": hinge}

    # --------------------------------------------------------------------------- prediction
    def _check_fitted(self) -> None:
        if not hasattr(self, "alpha_"):
            raise ConfigError(f"{self.key}.fit", "model is not fitted; call fit(X, f) first")

    def _kernel(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        diff = (A[:, None, :] - B[None, :, :]) / self.length_scales_
        return self.signal_var_ * np.exp(-0.5 * np.sum(diff**2, axis=2))

    def _check_x(self, X: Any, ndim: int) -> np.ndarray:
        self._check_fitted()
        X = _as_array(f"{self.key}.X", X, ndim)
        if X.shape[-1] != self._d:
            raise ConfigError(f"{self.key}.X", f"must have {self._d} columns, got {X.shape}")
        return X

    def predict(self, X: Any, return_var: bool = True) -> Any:
        """Posterior mean (and latent variance, no noise) at poses X, shape (N, d) (Eq. 2)."""
        X = self._check_x(X, 2)
        ks = self._kernel(X, self._X)
        mu = self._mean_fn(X, self.hinge_) + ks @ self.alpha_
        if not return_var:
            return mu
        v = ks @ self.L_inv_.T
        return mu, np.maximum(self.signal_var_ - np.sum(v**2, axis=1), 0.0)

    def mean_gradient(self, x: Any) -> np.ndarray:
        """Analytic d mu / d x at one pose x, shape (d,); right derivative at the hinge kink."""
        x = self._check_x(x, 1)
        ks = self._kernel(x[None, :], self._X)[0]
        grad = -((x - self._X) / self.length_scales_**2).T @ (ks * self.alpha_)
        if self.hinge_ is not None:
            c1, c2, c3 = self.hinge_
            xi = x[self.hinge_input]
            if self.hinge_form == "smooth":
                grad[self.hinge_input] += c2 * self._hinge_parts(np.array([xi]), c3)[1][0]
            elif xi >= c3:  # both kinked forms have slope c2 on the right of the kink
                grad[self.hinge_input] += c2
        return grad

    def _casadi_exprs(self, x: ca.MX) -> tuple[ca.MX, ca.MX]:
        M = self._X.shape[0]
        Xs = ca.DM(self._X / self.length_scales_)
        xs = x / ca.DM(self.length_scales_)
        ks = self.signal_var_ * ca.exp(-0.5 * ca.sum2((Xs - ca.repmat(xs.T, M, 1)) ** 2))
        mu = ca.dot(ks, ca.DM(self.alpha_))
        if self.hinge_ is not None:
            c1, c2, c3 = self.hinge_
            xi = x[self.hinge_input]
            if self.hinge_form == "continuous":
                mu = mu + c1 + c2 * ca.fmax(0.0, xi - c3)
            elif self.hinge_form == "smooth":  # stable softplus: max(z, 0) + log1p(exp(-|z|))
                z = (xi - c3) / self.hinge_width
                soft = ca.fmax(z, 0.0) + ca.log1p(ca.exp(-ca.fabs(z)))
                mu = mu + c1 + c2 * self.hinge_width * soft
            else:
                mu = mu + ca.if_else(xi <= c3, c1, c1 + c2 * xi)
        v = ca.mtimes(ca.DM(self.L_inv_), ks)
        return mu, self.signal_var_ - ca.dot(v, v)

    def casadi_functions(self) -> dict[str, ca.Function]:
        """Casadi ``MX`` functions of x (d,): "mean" -> mu, "var" -> latent var, "grad" -> (d,)."""
        self._check_fitted()
        x = ca.MX.sym("x", self._d)
        mu, var = self._casadi_exprs(x)
        grad = ca.jacobian(mu, x).T
        return {
            "mean": ca.Function("gp_mean", [x], [mu], ["x"], ["mu"]),
            "var": ca.Function("gp_var", [x], [var], ["x"], ["var"]),
            "grad": ca.Function("gp_grad", [x], [grad], ["x"], ["dmu_dx"]),
        }
