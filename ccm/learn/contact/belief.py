"""One expected contact as a Gaussian belief N(c, P) in task space (seed A §3.3).

Contacts are stationary (§3.3: A = I, B u = 0), so the Kalman predict step between trials
only adds the process noise Q; the measurement is the end-effector position (forward
kinematics) at the detected contact, H = I, noise R. The ellipsoid
{x : (x - c)^T P^-1 (x - c) <= s^2} at sigma scale s is the belief's own uncertainty region
(:meth:`ContactBelief.region_contains`); the controller's region C of anticipated mode
transition is that of the innovation covariance P + R, where the next detected contact is
expected (:mod:`ccm.control.adaptive.contact_regions`). Seed A §3.3 calls C the "covariance
ellipsoid" and states no sigma scale. :class:`ccm.learn.contact.contacts.ContactMap` holds one
belief per expected contact.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ccm.core.errors import ConfigError, check_finite, check_nonneg, check_positive, check_vector


def matrix(key: str, value: Any, d: int, *, definite: bool) -> np.ndarray:
    """A symmetric (d, d) covariance, positive definite if ``definite`` else semi-definite."""
    try:
        m = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(key, f"must be a {d}x{d} matrix of numbers") from None
    if m.shape != (d, d) or not np.all(np.isfinite(m)) or not np.allclose(m, m.T, atol=1e-15):
        raise ConfigError(key, f"must be a finite symmetric {d}x{d} matrix")
    m = 0.5 * (m + m.T)
    lo = float(np.linalg.eigvalsh(m)[0])
    if (lo <= 0.0) if definite else (lo < -1e-12 * float(np.abs(m).max())):
        kind = "positive definite" if definite else "positive semi-definite"
        raise ConfigError(key, f"must be {kind} (smallest eigenvalue {lo:.3g})")
    return m


def std_vector(key: str, value: Any, d: int, positive: bool = True) -> np.ndarray:
    """Per-axis standard deviations (m) from a scalar or a length-d list."""
    s = np.full(d, check_finite(key, value)) if np.isscalar(value) else check_vector(key, value, d)
    if np.any(s < 0.0) or (positive and np.any(s == 0.0)):
        raise ConfigError(key, f"must be {'> 0' if positive else '>= 0'}, got {value!r}")
    return s


class ContactBelief:
    """Belief N(c, P) about one contact position, Kalman-filtered across trials (§3.3, seed A).

    Args:
        mean: Contact position c, shape (2,) or (3,), m (task space).
        cov: P, (d, d), m^2, positive definite.
        process_noise_cov: Q, (d, d), positive semi-definite: uncertainty w added between
            trials by :meth:`predict` (zero for a contact known to be perfectly static).
        measurement_noise_cov: R, (d, d), positive definite: noise of the end-effector position
            measured at the detected contact (encoders, forward kinematics, detection delay).
        key: Configuration key used as the prefix of error messages.
    """

    def __init__(
        self,
        mean: Any,
        cov: Any,
        process_noise_cov: Any,
        measurement_noise_cov: Any,
        key: str = "controller.contacts.belief",
    ) -> None:
        self.key = key
        self.mean = check_vector(f"{key}.mean", mean, (2, 3))
        d = self.dim
        self.cov = matrix(f"{key}.cov", cov, d, definite=True)
        self.Q = matrix(f"{key}.process_noise_cov", process_noise_cov, d, definite=False)
        self.R = matrix(f"{key}.measurement_noise_cov", measurement_noise_cov, d, definite=True)
        self.n_updates = 0

    @property
    def dim(self) -> int:
        """Task-space dimension d (2 or 3)."""
        return int(self.mean.shape[0])

    @property
    def std(self) -> np.ndarray:
        """Per-axis standard deviation sqrt(diag P), m: the "±" of seed A Table 1."""
        return np.sqrt(np.diag(self.cov))

    @property
    def axes_std(self) -> np.ndarray:
        """Semi-axes of the 1σ ellipsoid, sqrt(eigenvalues of P), ascending, m."""
        return np.sqrt(np.linalg.eigvalsh(self.cov))

    def predict(self) -> ContactBelief:
        """Between trials: c unchanged (A = I, B u = 0), P <- P + Q (§3.3)."""
        self.cov = self.cov + self.Q
        return self

    def update(self, z: Any) -> ContactBelief:
        """Kalman correction with the end-effector position ``z`` at the detected contact.

        H = I: K = P (P + R)^-1, c <- c + K (z - c) and, in Joseph form,
        P <- (I - K) P (I - K)^T + K R K^T, symmetrised: it stays positive definite under
        rounding, which the short form (I - K) P does not guarantee.
        """
        z = check_vector(f"{self.key}.z", z, self.dim)
        p, r = self.cov, self.R
        gain = np.linalg.solve(p + r, p).T  # P S^-1, as P and S are symmetric
        self.mean = self.mean + gain @ (z - self.mean)
        a = np.eye(self.dim) - gain
        joseph = a @ p @ a.T + gain @ r @ gain.T
        self.cov = 0.5 * (joseph + joseph.T)
        self.n_updates += 1
        return self

    def mahalanobis(
        self, x: Any, cov: np.ndarray | None = None, name: str = "x"
    ) -> float | np.ndarray:
        """sqrt((x - c)^T P^-1 (x - c)): a float for x of shape (d,), an array for (N, d).

        ``cov`` replaces P, e.g. by the innovation covariance P + R.
        """
        try:
            pts = np.asarray(x, dtype=float)
        except (TypeError, ValueError):
            raise ConfigError(f"{self.key}.{name}", "must be an array of numbers") from None
        if pts.shape[-1:] != (self.dim,) or pts.ndim > 2 or not np.all(np.isfinite(pts)):
            shape = f"({self.dim},) or (N, {self.dim})"
            raise ConfigError(f"{self.key}.{name}", f"must be finite, of shape {shape}")
        chol = np.linalg.cholesky(self.cov if cov is None else cov)
        w = np.linalg.solve(chol, np.atleast_2d(pts - self.mean).T)
        dist = np.sqrt(np.sum(w * w, axis=0))
        return float(dist[0]) if pts.ndim == 1 else dist

    def region_contains(
        self, x: Any, sigma_scale: float, name: str = "x", min_radius: float = 0.0
    ) -> bool | np.ndarray:
        """Whether x (one point or (N, d)) is in C: Mahalanobis distance <= ``sigma_scale``.

        ``min_radius`` [m] floors C's semi-axes: the distance is taken with P + (r/s)² I, so C
        never shrinks below a ball of radius r however certain the belief becomes.
        """
        s = check_positive(f"{self.key}.sigma_scale", sigma_scale)
        r = check_nonneg(f"{self.key}.min_radius", min_radius)
        cov = None if r == 0.0 else self.cov + (r / s) ** 2 * np.eye(self.dim)
        inside = np.asarray(self.mahalanobis(x, cov=cov, name=name)) <= s
        return bool(inside) if inside.ndim == 0 else inside

    def first_entry(
        self, path_points: Any, sigma_scale: float, min_radius: float = 0.0
    ) -> int | None:
        """Index of the first point of a sampled path (N, d) inside C (p_c of §3.5), or None.

        Only samples are tested: space them more finely than the smallest semi-axis of C,
        ``sigma_scale * axes_std[0]``, or a path that crosses C between samples is missed.
        """
        inside = self.region_contains(path_points, sigma_scale, "path_points", min_radius)
        hits = np.flatnonzero(np.atleast_1d(inside))
        return int(hits[0]) if hits.size else None
