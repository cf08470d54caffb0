"""λ(ε) of seed A Eq. 4c, with ε₀ and r given or set from the prediction errors.

    λ = 1 − 1 / (1 + exp(−r (ε − ε₀)))                                  (4c)

ε₀ and r from data (``calibrate``). Seed A tunes r and ε₀ "for the task". With
``calibrate: {trials, quantile, shape}`` they are set from the prediction errors instead:
the first ``trials`` trials in which the model predicts run at K_max without feed-forward
(the model is new, as after a new mode in Algorithm 1) while it learns and every ε_t is kept
(a frozen model that only fits at the end of a trial gives its errors on its training window
instead); then
ε₀ = the ``quantile`` of those errors and r = ``shape`` / ε₀, so λ(ε₀/2) = 1/(1 + e^{−shape/2})
and λ(3ε₀/2) = 1 − that (shape 10: 0.993 and 0.007). experiments/tuning/avic.md records why.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ccm.control.base import check_state_keys
from ccm.core.errors import (
    ConfigError,
    check_int_positive,
    check_keys,
    check_nonneg,
    check_positive,
)
from ccm.core.filters import lowpass_sequence

_CALIBRATE_KEYS = ("trials", "quantile", "shape")


def check_calibrate(cfg: Mapping[str, Any] | None, key: str) -> dict[str, float] | None:
    """Validate ``calibrate: {trials >= 1, quantile in (0, 1), shape > 0}`` (or None)."""
    if cfg is None:
        return None
    if not isinstance(cfg, Mapping):
        raise ConfigError(
            key, f"must be a mapping {{trials, quantile, shape}} or null, got {cfg!r}"
        )
    check_keys(key, cfg, _CALIBRATE_KEYS)
    q = check_positive(f"{key}.quantile", cfg.get("quantile", 0.9))
    if q >= 1.0:
        raise ConfigError(f"{key}.quantile", f"must be in (0, 1), got {q!r}")
    return {
        "trials": check_int_positive(f"{key}.trials", cfg.get("trials", 1)),
        "quantile": q,
        "shape": check_positive(f"{key}.shape", cfg.get("shape", 10.0)),
    }


class LogisticGate:
    """Eq. 4c's λ(ε) and its parameters, held by :class:`ccm.control.adaptive.avic.AVIC`.

    Args:
        r: growth rate [1/N]; None with ``calibrate``.
        eps0: midpoint ε₀ [N]; None with ``calibrate``.
        calibrate: ``{trials, quantile, shape}`` (module docstring), or None.
        active: False for a controller that never uses λ (the non-adaptive baseline): it
            never calibrates.
        key: the controller's config key (errors name ``<key>.r``, ``<key>.calibrate.*``).
    """

    def __init__(
        self,
        r: float | None,
        eps0: float | None,
        calibrate: Mapping[str, Any] | None = None,
        active: bool = True,
        key: str = "controller",
    ) -> None:
        self.calibrate = check_calibrate(calibrate, f"{key}.calibrate")
        self.active = active
        if self.calibrate is not None:
            for name, value in (("r", r), ("eps0", eps0)):
                if value is not None:
                    raise ConfigError(
                        f"{key}.{name}", f"is set by {key}.calibrate: give null, got {value!r}"
                    )
            self.r, self.eps0 = math.nan, math.nan  # until calibrated
        else:
            self.r = check_positive(f"{key}.r", r)
            self.eps0 = check_nonneg(f"{key}.eps0", eps0)
        self._errors: list[float] = []
        self._trials = 0

    @property
    def calibrating(self) -> bool:
        """True while ``calibrate`` still collects the errors that set ε₀ and r."""
        cal = self.calibrate
        return self.active and cal is not None and self._trials < cal["trials"]

    def __call__(self, eps: float) -> float:
        """λ(ε) of Eq. 4c, in [0, 1]; numerically safe for any ε."""
        z = -self.r * (eps - self.eps0)  # λ = 1 − 1/(1 + e^z) = e^z / (1 + e^z)
        if z >= 0.0:
            return 1.0 / (1.0 + math.exp(-z))
        ez = math.exp(z)
        return ez / (1.0 + ez)

    def keep(self, err: float) -> None:
        """Keep one (low-passed) prediction error while calibrating."""
        self._errors.append(err)

    def end_trial(self, fit_errors: Sequence[float] | None, alpha: float) -> None:
        """Count a calibration trial; after the last one set ε₀ and r (module docstring). A
        trial in which the model made no prediction does not count, unless a frozen model
        gives its training window's errors ``fit_errors`` (low-passed here with ``alpha``):
        the controller stays at K_max until it has errors to go by."""
        if not self.calibrating:
            return
        cal = self.calibrate
        assert cal is not None
        errs = np.asarray(self._errors, dtype=float)
        if errs.size == 0 and fit_errors is not None and len(fit_errors):
            errs = lowpass_sequence(np.asarray(fit_errors, dtype=float), alpha)
        if errs.size == 0:
            return
        self._trials += 1
        if self.calibrating:
            return
        self.eps0 = max(float(np.quantile(errs, cal["quantile"])), 1e-9)
        self.r = cal["shape"] / self.eps0
        self._errors = []

    def params(self) -> dict[str, float | None]:
        """ε₀ and r, None until calibrated (or when a non-adaptive controller never is)."""
        return {
            k: (v if math.isfinite(v) else None) for k, v in (("eps0", self.eps0), ("r", self.r))
        }

    def state_dict(self) -> dict[str, Any]:
        """JSON-safe calibration progress: trials done, ε₀ and r once set, the errors kept."""
        cal = self.calibrate is not None and not self.calibrating
        params = self.params() if cal else {"eps0": None, "r": None}
        return {"trials": self._trials, **params, "errors": list(self._errors)}

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state_dict` output (ValueError if it does not fit)."""
        check_state_keys(state, ("trials", "eps0", "r", "errors"))
        trials = int(state["trials"])
        errors = [float(e) for e in state["errors"]]
        if self.calibrate is None:
            if trials or errors or state["eps0"] is not None:
                raise ValueError("the saved controller was calibrated; this config is not")
            return
        eps0, r = self.eps0, self.r
        if trials >= self.calibrate["trials"] and state["eps0"] is not None:
            eps0, r = check_positive("eps0", state["eps0"]), check_positive("r", state["r"])
        self.eps0, self.r = eps0, r
        self._trials, self._errors = trials, errors
