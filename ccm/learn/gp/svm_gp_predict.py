"""Predictions of the offline modal GP baseline (Khader et al. 2020; seed A §4.4, Figs 11-14).

:class:`ModalGPPrediction` is the base of :class:`ccm.learn.gp.svm_gp.ModalGPDynamics`, which
fits the SVC mode classifier and the per-mode GPs; from the fitted model this predicts the
mode of a state (the SVC), one step with feedback (variant iii, §4.4.3) and the long-horizon
Monte-Carlo rollout (variants i and ii, §4.4.1-4.4.2).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ccm.core.errors import ConfigError, check_int_positive

__all__ = ["ModalGPPrediction"]


def _as_matrix(key: str, value: Any) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(key, "must be a numeric array") from None
    if arr.ndim != 2 or arr.shape[0] == 0 or arr.shape[1] == 0:
        raise ConfigError(key, f"must be a non-empty 2-D array, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ConfigError(key, "must be finite (found NaN or inf)")
    return arr


class ModalGPPrediction:
    """Mode, one-step and rollout predictions of a fitted
    :class:`ccm.learn.gp.svm_gp.ModalGPDynamics` (which sets every attribute below in ``fit``).
    """

    key: str
    predict_delta: bool
    n_particles: int
    seed: int
    classes_: np.ndarray
    n_modes_: int
    d_in_: int
    d_out_: int
    x_mean_: np.ndarray
    x_std_: np.ndarray
    svc_: Any
    gps_: list[list[Any]]
    gp_x_mean_: list[np.ndarray]
    gp_x_std_: list[np.ndarray]

    def _check_fitted(self) -> None:
        if not hasattr(self, "gps_"):
            raise ConfigError(f"{self.key}.fit", "model is not fitted; call fit() first")

    def _mode_index(self, X: np.ndarray) -> np.ndarray:
        """Index into ``classes_`` of the SVC-predicted mode for each row of X."""
        if self.svc_ is None:
            return np.zeros(X.shape[0], dtype=int)
        labels = self.svc_.predict((X - self.x_mean_) / self.x_std_)
        return np.searchsorted(self.classes_, labels)

    def _gp_predict(self, m: int, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean and std (n, d_out) of mode m's GPs (the targets, i.e. increments if delta)."""
        xz = (X - self.gp_x_mean_[m]) / self.gp_x_std_[m]
        means, stds = [], []
        for gp in self.gps_[m]:
            mu, sd = gp.predict(xz, return_std=True)
            means.append(mu.reshape(X.shape[0], -1))
            stds.append(sd.reshape(X.shape[0], -1))
        return np.hstack(means), np.hstack(stds)

    def _predict_by_mode(self, X: np.ndarray, mode_idx: np.ndarray) -> tuple[np.ndarray, ...]:
        mean = np.empty((X.shape[0], self.d_out_))
        std = np.empty_like(mean)
        for m in np.unique(mode_idx):
            rows = mode_idx == m
            mean[rows], std[rows] = self._gp_predict(int(m), X[rows])
        if self.predict_delta:
            mean += X[:, : self.d_out_]
        return mean, std

    def predict_mode(self, X: np.ndarray) -> np.ndarray:
        """SVC-predicted mode label per row of X, shape (N,)."""
        self._check_fitted()
        X = self._check_inputs(X)
        return self.classes_[self._mode_index(X)]

    def _check_inputs(self, X: np.ndarray) -> np.ndarray:
        X = _as_matrix(f"{self.key}.X", X)
        if X.shape[1] != self.d_in_:
            raise ConfigError(f"{self.key}.X", f"needs {self.d_in_} columns, got {X.shape[1]}")
        return X

    def predict_step(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One-step prediction with feedback (seed A §4.4.3, variant iii).

        Args:
            X: current inputs, shape (N, d_in).

        Returns:
            ``(mean, std)``, each (N, d_out): the GP of the SVC-predicted mode per row; std is
            the GP's predictive std (it includes the learned noise level).
        """
        self._check_fitted()
        X = self._check_inputs(X)
        return self._predict_by_mode(X, self._mode_index(X))

    def rollout(
        self, x0: np.ndarray, steps: int, exog: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Long-horizon probabilistic prediction by Monte-Carlo particles (seed A §4.4.1-2).

        Propagation is by sampling, not moment matching: at a mode boundary some particles
        switch mode and others do not, so the predictive distribution becomes multi-modal,
        which a single propagated Gaussian cannot represent. ``n_particles`` copies of ``x0``
        are propagated; at step k each particle gets its mode from the SVC, that mode's GP
        mean/std, and a sample ``y ~ N(mean, std^2)`` (seeded generator, so the same seed
        gives identical arrays). The next input is the sampled output, followed by
        ``exog[k + 1]`` if exogenous inputs are given.

        Args:
            x0: initial input, shape (d_in,).
            steps: number of predicted steps (>= 1).
            exog: required iff ``d_in > d_out``: shape (steps, d_in - d_out), or steps + 1
                rows (a whole trial; the last row is then unused); row k holds the exogenous
                columns of the input at step k (row 0 replaces ``x0[d_out:]``), e.g. the test
                trial's planned or measured velocity (variant ii).

        Returns:
            ``(mean, std, mode_fraction)``: mean and std over particles of the prediction for
            t+k+1, each (steps, d_out); mode_fraction (steps, n_modes) the share of particles
            in each mode (order of ``classes_``) when predicting step k.
        """
        self._check_fitted()
        k = self.key
        steps = check_int_positive(f"{k}.steps", steps)
        x0 = np.asarray(x0, dtype=float)
        if x0.shape != (self.d_in_,) or not np.all(np.isfinite(x0)):
            raise ConfigError(f"{k}.x0", f"must be a finite vector of length {self.d_in_}")
        d_ex = self.d_in_ - self.d_out_
        if d_ex > 0:
            if exog is None:
                raise ConfigError(f"{k}.exog", f"needed: inputs have {d_ex} exogenous columns")
            exog = np.asarray(exog, dtype=float)
            if exog.ndim != 2 or exog.shape[0] not in (steps, steps + 1) or exog.shape[1] != d_ex:
                raise ConfigError(
                    f"{k}.exog",
                    f"must have shape ({steps} or {steps + 1}, {d_ex}), got {exog.shape}",
                )
            if not np.all(np.isfinite(exog)):
                raise ConfigError(f"{k}.exog", "must be finite (found NaN or inf)")
            x0 = np.concatenate([x0[: self.d_out_], exog[0]])
        elif exog is not None:
            raise ConfigError(f"{k}.exog", "must be None: the inputs have no exogenous columns")

        rng = np.random.default_rng(self.seed)
        x = np.tile(x0, (self.n_particles, 1))
        mean = np.empty((steps, self.d_out_))
        std = np.empty_like(mean)
        frac = np.empty((steps, self.n_modes_))
        for t in range(steps):
            mode_idx = self._mode_index(x)
            frac[t] = np.bincount(mode_idx, minlength=self.n_modes_) / self.n_particles
            mu, sd = self._predict_by_mode(x, mode_idx)
            y = mu + sd * rng.standard_normal(mu.shape)
            mean[t] = y.mean(axis=0)
            std[t] = y.std(axis=0)
            if t + 1 < steps:
                x = np.hstack([y, np.tile(exog[t + 1], (self.n_particles, 1))]) if d_ex else y
        return mean, std, frac
