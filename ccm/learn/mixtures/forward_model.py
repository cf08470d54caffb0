"""Forward models of the interaction dynamics in wrench-magnitude space (seed A §3.1).

A point is X_t = [S_{t−1}, D_t] with (Eq. 2, 3)

    S = [‖ẋ_lin‖, ‖ẋ_rot‖, ‖F‖, ‖τ‖],   D = [‖F‖, ‖τ‖],

and a model predicts D_{t+1} from S_t by GMR (Eq. 6). Here "t + 1" is one *model* step, the
horizon ``horizon_s`` = H control periods: points are X_t = [S_{t−H}, D_t] and the model
predicts D_{t+H} from S_t, while control stays at 1 kHz
(:class:`~ccm.learn.mixtures.forecast.ForecastBuffer` keeps the pairs). One control step ahead, a
prediction from ‖F_t‖ cannot beat persistence (D̂_{t+1} = D_t) under sensor noise;
experiments/tuning/forward_model_horizon.md measures the skill against the horizon.
Magnitudes make the model independent
of the direction of motion; the controller turns a predicted magnitude back into a vector
(see :mod:`ccm.control.adaptive.avic`). Features are divided by ``feature_scale`` (their typical
size, in their own units) before they reach the mixture, so that one isotropic initial covariance
suits speeds in m/s and forces in N alike.

* :class:`IncrementalForwardModel` — IGMM revised at every step (seed A's model).
* :class:`FrozenGMMForwardModel` — scikit-learn ``GaussianMixture`` fit once on the first
  ``fit_steps`` points, then frozen (seed A §4.1's fixed-GMM baseline).

Both save what they learned with ``state_dict()`` (JSON-safe) and take it back with
``load_state_dict()`` on a model built from the config: the settings stay the config's, the
kind, feature scale and horizon must match.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ccm.core.errors import (
    ConfigError,
    check_choice,
    check_int_positive,
    check_keys,
    check_positive,
    constructor_kwargs,
)
from ccm.core.protocols import ForwardModel

N_STATE = 4
N_EFFECT = 2
IN_IDX = np.arange(N_STATE)
OUT_IDX = np.arange(N_STATE, N_STATE + N_EFFECT)
#: typical magnitudes of [‖v‖ m/s, ‖ω‖ rad/s, ‖F‖ N, ‖τ‖ N m, ‖F‖ N, ‖τ‖ N m] (chosen)
DEFAULT_SCALE = (0.1, 1.0, 10.0, 1.0, 10.0, 1.0)
#: prediction horizon [s] when a config gives none: one 1 kHz control step (seed A's "next
#: time step"; the configs set the horizon of experiments/tuning/forward_model_horizon.md)
DEFAULT_HORIZON_S = 0.001


def magnitudes(
    lin_vel: np.ndarray, ang_vel: np.ndarray, force: np.ndarray, torque: np.ndarray
) -> np.ndarray:
    """S_t of Eq. 2: [‖ẋ_lin‖, ‖ẋ_rot‖, ‖F‖, ‖τ‖]."""
    return np.array(
        [
            math.hypot(*lin_vel.tolist()),
            math.hypot(*ang_vel.tolist()),
            math.hypot(*force.tolist()),
            math.hypot(*torque.tolist()),
        ]
    )


def _check_scale(scale: Sequence[float], key: str) -> np.ndarray:
    arr = np.asarray(list(scale), dtype=float)
    if arr.shape != (N_STATE + N_EFFECT,):
        raise ConfigError(key, f"needs {N_STATE + N_EFFECT} values, got {list(scale)!r}")
    for i, v in enumerate(arr):
        check_positive(f"{key}[{i}]", v)
    return arr


def _check_state(data: Mapping[str, Any], kind: str, scale: np.ndarray, horizon_s: float) -> None:
    """A saved forward model must be of this config's ``kind``, feature scale (its numbers
    are in the scaled units) and horizon (it maps S_t to D_{t+H})."""
    if not isinstance(data, Mapping):
        raise ValueError(f"forward model state must be a mapping, got {type(data).__name__}")
    if data.get("kind") != kind:
        raise ValueError(
            f"the saved forward model is kind {data.get('kind')!r}, this config's is {kind!r}"
        )
    saved = np.asarray(data.get("feature_scale"), dtype=float)
    if saved.shape != scale.shape or not np.array_equal(saved, scale):
        raise ValueError(
            f"the saved forward model has feature_scale {data.get('feature_scale')!r}, "
            f"this config's is {scale.tolist()!r}"
        )
    if data.get("horizon_s") != horizon_s:
        raise ValueError(
            f"the saved forward model has horizon_s {data.get('horizon_s')!r}, "
            f"this config's is {horizon_s!r}"
        )


class IncrementalForwardModel:
    """IGMM forward model revised online (seed A §3.1, Eq. 5–6).

    Args:
        feature_scale: divisor per feature of X = [S, D] (6 values).
        igmm: keyword arguments of :class:`ccm.learn.mixtures.igmm.IGMM`.
        horizon_s: H, the time between S and the D it predicts [s]; whoever feeds the model
            pairs H apart (:class:`~ccm.learn.mixtures.forecast.ForecastBuffer`) reads it.
        key: config prefix for error messages.
    """

    def __init__(
        self,
        feature_scale: Sequence[float] = DEFAULT_SCALE,
        igmm: dict[str, Any] | None = None,
        horizon_s: float = DEFAULT_HORIZON_S,
        key: str = "controller.forward_model",
    ) -> None:
        from ccm.learn.mixtures import _forward_kernels  # numba: only for this model
        from ccm.learn.mixtures.igmm import IGMM

        self._fit_scaled = _forward_kernels.fit_scaled
        self._predict_scaled = _forward_kernels.predict_scaled
        self._fit_predict_scaled = _forward_kernels.fit_predict_scaled
        self.scale = _check_scale(feature_scale, f"{key}.feature_scale")
        self.horizon_s = check_positive(f"{key}.horizon_s", horizon_s)
        self.model = IGMM(N_STATE + N_EFFECT, **(igmm or {}), key=f"{key}.igmm")
        # reused buffers of the per-step kernel calls (ccm.learn.mixtures._forward_kernels)
        self._x = np.empty((1, N_STATE + N_EFFECT))
        self._x_in = np.empty((1, N_STATE))
        self._y = np.empty((1, N_EFFECT))
        self._no_cov = np.zeros((1, N_EFFECT, N_EFFECT))
        self._bind(self.model)

    def _bind(self, model: Any) -> None:
        """Use ``model``: its GMR view (refreshed by the model itself) and the buffers both
        hand to the kernels (fixed for the model's life)."""
        self.model = model
        self._gmr = model.conditional(IN_IDX, OUT_IDX)
        self._fit_buffers = model.kernel_buffers()
        self._gmr_buffers = self._gmr.kernel_buffers()
        self._split_cache = (self._gmr_buffers[0], self._gmr_buffers[-1])

    @property
    def ready(self) -> bool:
        """True once the model has a component to predict with."""
        return self.model.n_components_ > 0

    def update(self, s_prev: np.ndarray, d_now: np.ndarray) -> None:
        """Add X_t = [S_{t−1}, D_t] / scale (Eq. 5, one incremental step; one kernel call).

        Raises:
            ValueError: a non-finite point (the model is left unchanged).
        """
        if self._fit_scaled(s_prev, d_now, self.scale, self._x, *self._fit_buffers):
            raise ValueError("X: the point is not finite; the model was not changed")

    def predict(self, s_now: np.ndarray) -> np.ndarray:
        """D̂_{t+1} = f_fm(S_t) by GMR on S_t / scale, times the scale of D (Eq. 6; one kernel
        call); zeros before the first point."""
        out = np.empty(N_EFFECT)
        status = self._predict_scaled(
            s_now, self.scale, self._x_in, *self._gmr_buffers, self._y, self._no_cov, out
        )
        if status == -1:  # no component yet
            return np.zeros(N_EFFECT)
        if status:
            self._gmr.raise_status(status)
        return out

    def update_predict(
        self, s_prev: np.ndarray, d_now: np.ndarray, s_now: np.ndarray
    ) -> np.ndarray | None:
        """:meth:`update` with [S_{t−1}, D_t], then :meth:`predict` from S_t (one kernel call;
        None if the model has no component to predict with).

        Raises:
            ValueError: a non-finite point (the model is left unchanged).
        """
        out = np.empty(N_EFFECT)
        status = self._fit_predict_scaled(
            s_prev, d_now, s_now, self.scale, self._x, self._x_in, self._y, self._no_cov, out,
            *self._fit_buffers, *self._split_cache,
        )  # fmt: skip
        if status == 1:
            raise ValueError("X: the point is not finite; the model was not changed")
        if status == -1:
            return None
        if status:
            self._gmr.raise_status(status)
        return out

    def end_trial(self) -> None:
        """Nothing to do: the model learns every step."""

    @property
    def n_components(self) -> int:
        return int(self.model.n_components_)

    def state_dict(self) -> dict[str, Any]:
        """JSON-safe learned state: kind, feature scale and the IGMM snapshot
        (:meth:`ccm.learn.mixtures.igmm.IGMM.state_dict`)."""
        return {
            "kind": "igmm",
            "feature_scale": self.scale.tolist(),
            "horizon_s": self.horizon_s,
            "igmm": self.model.state_dict(),
        }

    def load_state_dict(self, data: Mapping[str, Any]) -> None:
        """Take the components of a :meth:`state_dict`; the IGMM settings stay this model's.

        Raises:
            ValueError: another kind or feature scale, or a malformed or foreign snapshot
                (e.g. more components than this config's ``max_components``).
        """
        from ccm.learn.mixtures.igmm import IGMM

        _check_state(data, "igmm", self.scale, self.horizon_s)
        snap = data.get("igmm")
        if not isinstance(snap, Mapping):
            raise ValueError("forward model state: igmm must be a mapping")
        try:
            snap = {**snap, "params": self.model.get_params()}
            model = IGMM.from_state_dict(snap, key=self.model.key)
        except ConfigError as exc:
            raise ValueError(str(exc)) from None
        self._bind(model)


class FrozenGMMForwardModel:
    """Fixed GMM baseline (seed A §4.1): batch-fit on its training window, then frozen.

    Points are collected across trials until ``fit_steps`` are seen, or (``fit_steps=None``)
    until the end of the first trial that gave any; the mixture is fit then and never
    revised. Before the fit it predicts zeros (and says so through ``ready``).

    Args:
        fit_steps: number of points in the training window ("the initial phase"), or None:
            the points of the first trial (seed A §4.1: "the sensor measurements collected
            during the initial phase"; a horizon of H steps gives a trial H fewer points).
            At least 2.
        n_components: mixture size for ``sklearn.mixture.GaussianMixture``.
        feature_scale: as for :class:`IncrementalForwardModel`.
        random_state: seed of the k-means initialisation (reproducible fits).
        reg_covar: covariance regulariser passed to scikit-learn.
        horizon_s: as for :class:`IncrementalForwardModel`.
    """

    def __init__(
        self,
        fit_steps: int | None = 6000,
        n_components: int = 1,
        feature_scale: Sequence[float] = DEFAULT_SCALE,
        random_state: int = 0,
        reg_covar: float = 1e-6,
        horizon_s: float = DEFAULT_HORIZON_S,
        key: str = "controller.forward_model",
    ) -> None:
        self.fit_steps = (
            None if fit_steps is None else check_int_positive(f"{key}.fit_steps", fit_steps)
        )
        if self.fit_steps == 1:  # scikit-learn fits a mixture to two points or more
            raise ConfigError(f"{key}.fit_steps", "must be >= 2 (a mixture needs two points)")
        self.n_components = check_int_positive(f"{key}.n_components", n_components)
        self.scale = _check_scale(feature_scale, f"{key}.feature_scale")
        self.horizon_s = check_positive(f"{key}.horizon_s", horizon_s)
        self.random_state = int(random_state)
        self.reg_covar = check_positive(f"{key}.reg_covar", reg_covar)
        self._buf = np.empty((self.fit_steps or 4096, N_STATE + N_EFFECT))
        self._n = 0
        self._params: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        #: ‖D − D̂‖ on the training window once fit, in order (AVIC's calibration of ε₀
        #: uses them when the model could not predict during its calibration trials)
        self.fit_errors = np.zeros(0)

    @property
    def ready(self) -> bool:
        return self._params is not None

    def update(self, s_prev: np.ndarray, d_now: np.ndarray) -> None:
        """Collect X_t until the training window is full, then fit once."""
        if self._params is not None:
            return
        if self._n == len(self._buf):  # fit_steps=None: the window grows with the trial
            self._buf = np.concatenate([self._buf, np.empty_like(self._buf)])
        self._buf[self._n, :N_STATE] = s_prev
        self._buf[self._n, N_STATE:] = d_now
        self._n += 1
        if self._n == self.fit_steps:
            self._fit()

    def _fit(self) -> None:
        from sklearn.mixture import GaussianMixture

        X = self._buf[: self._n] / self.scale
        k = min(self.n_components, len(X))
        gm = GaussianMixture(
            n_components=k,
            covariance_type="full",
            reg_covar=self.reg_covar,
            random_state=self.random_state,
        ).fit(X)
        from ccm.learn.mixtures.gmr import GMRConditional

        self._params = (gm.weights_.copy(), gm.means_.copy(), gm.covariances_.copy())
        self._gmr = GMRConditional(*self._params, IN_IDX, OUT_IDX)  # cached factorisations
        pts = self._buf[: self._n]
        pred = np.array([self.predict(x) for x in pts[:, :N_STATE]])
        self.fit_errors = np.linalg.norm(pts[:, N_STATE:] - pred, axis=1)
        self._buf = np.empty((0, N_STATE + N_EFFECT))

    def predict(self, s_now: np.ndarray) -> np.ndarray:
        """D̂_{t+1} by GMR on the frozen mixture (Eq. 6); zeros before the fit."""
        if self._params is None:
            return np.zeros(N_EFFECT)
        mean = self._gmr.predict(s_now / self.scale[:N_STATE])
        return np.asarray(mean, dtype=float) * self.scale[N_STATE:]

    def end_trial(self) -> None:
        """With ``fit_steps=None``, fit on the first trial's points; else nothing to do. A
        trial that gave fewer than two points (too short for one pair H apart, or for a
        mixture) leaves the window open into the next."""
        if self.fit_steps is None and self._params is None and self._n >= 2:
            self._fit()

    def state_dict(self) -> dict[str, Any]:
        """JSON-safe learned state: the collected points before the fit, the mixture after."""
        fitted = None
        if self._params is not None:
            w, mu, cov = self._params
            fitted = {"weights": w.tolist(), "means": mu.tolist(), "covariances": cov.tolist()}
        return {
            "kind": "fixed_gmm",
            "feature_scale": self.scale.tolist(),
            "horizon_s": self.horizon_s,
            "points": self._buf[: self._n].tolist() if self._params is None else [],
            "fitted": fitted,
        }

    def load_state_dict(self, data: Mapping[str, Any]) -> None:
        """Take the points or the fitted mixture of a :meth:`state_dict`. Points that already
        fill this config's ``fit_steps`` window are fit now.

        Raises:
            ValueError: another kind or feature scale, or malformed arrays.
        """
        from ccm.learn.mixtures.gmr import GMRConditional

        _check_state(data, "fixed_gmm", self.scale, self.horizon_s)
        fitted = data.get("fitted")
        if fitted is not None:
            if not isinstance(fitted, Mapping):
                raise ValueError("forward model state: fitted must be a mapping or null")
            params = tuple(
                np.asarray(fitted[k], dtype=float) for k in ("weights", "means", "covariances")
            )
            gmr = GMRConditional(*params, IN_IDX, OUT_IDX)  # validates the mixture
            self._params, self._gmr = params, gmr  # type: ignore[assignment]
            self._buf = np.empty((0, N_STATE + N_EFFECT))
            self._n = 0
            return
        pts = np.asarray(data.get("points"), dtype=float).reshape(-1, N_STATE + N_EFFECT)
        if not np.all(np.isfinite(pts)):
            raise ValueError("forward model state: points must be finite")
        n = len(pts) if self.fit_steps is None else min(len(pts), self.fit_steps)
        self._buf = np.empty((max(self.fit_steps or 0, n, 1), N_STATE + N_EFFECT))
        self._buf[:n] = pts[:n]
        self._n, self._params = n, None
        if n == self.fit_steps:
            self._fit()


FORWARD_MODELS = {"igmm": IncrementalForwardModel, "fixed_gmm": FrozenGMMForwardModel}


def make_forward_model(cfg: dict[str, Any], key: str = "controller.forward_model") -> ForwardModel:
    """Build a forward model from ``{kind, feature_scale, horizon_s, igmm: {...},
    fixed_gmm: {...}}``.

    ``kind`` picks the model; only its own sub-mapping is used, so a config can carry the
    settings of both kinds and a condition can switch with ``forward_model.kind=…``.
    """
    cfg = dict(cfg or {})
    check_keys(key, cfg, ("kind", "feature_scale", "horizon_s", *FORWARD_MODELS))
    kind = check_choice(f"{key}.kind", cfg.get("kind", "igmm"), FORWARD_MODELS)
    shared = {
        "feature_scale": cfg.get("feature_scale", DEFAULT_SCALE),
        "horizon_s": cfg.get("horizon_s", DEFAULT_HORIZON_S),
    }
    sub = dict(cfg.get(kind) or {})
    if kind == "igmm":
        return IncrementalForwardModel(igmm=sub, **shared, key=key)
    kwargs = constructor_kwargs(FrozenGMMForwardModel, sub, f"{key}.{kind}")
    for k in shared:
        kwargs.pop(k, None)
    return FrozenGMMForwardModel(**kwargs, **shared, key=key)
