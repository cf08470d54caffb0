"""The multi-output GP force model of Haninger et al. (seed B, §3.1.1, Eq. 1-3).

:class:`GPForceModels` stacks one :class:`ccm.learn.gp.gp_force.GPForceModel` per force
dimension, each fitted independently, so the force covariance Σ_f is diagonal (seed B); its
casadi functions stack the per-output mean, variance and mean gradient for the GP-MPC
(:mod:`ccm.control.mpc.gp_mpc`). The single-output model, its kernel, hinge mean (Eq. 3) and
likelihood are :mod:`ccm.learn.gp.gp_force`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import casadi as ca
import numpy as np

from ccm.core.errors import ConfigError, check_int_positive
from ccm.learn.gp.gp_force import GPForceModel, _as_array

__all__ = ["GPForceModels"]


class GPForceModels:
    """One :class:`GPForceModel` per force dimension, fitted independently (diagonal Σ_f, seed B).

    Args:
        n_outputs: number of force dimensions (1-6).
        hinge_inputs: pose element each output's hinge acts on; default output j -> x[j].
        key: configuration-key prefix for errors; output j uses ``<key>.outputs[j]``.
        **kwargs: forwarded to every :class:`GPForceModel`.
    """

    def __init__(
        self,
        n_outputs: int,
        *,
        hinge_inputs: Sequence[int] | None = None,
        key: str = "gp",
        **kwargs: Any,
    ) -> None:
        self.key = key
        self.n_outputs = check_int_positive(f"{key}.n_outputs", n_outputs)
        if self.n_outputs > 6:
            raise ConfigError(f"{key}.n_outputs", f"must be <= 6, got {n_outputs}")
        if "hinge_input" in kwargs:
            raise ConfigError(f"{key}.hinge_input", "use hinge_inputs (one per output)")
        hin = list(range(self.n_outputs)) if hinge_inputs is None else list(hinge_inputs)
        if len(hin) != self.n_outputs:
            raise ConfigError(f"{key}.hinge_inputs", f"must have {self.n_outputs} entries")
        self.models = [
            GPForceModel(hinge_input=h, key=f"{key}.outputs[{j}]", **kwargs)
            for j, h in enumerate(hin)
        ]

    def fit(self, X: Any, F: Any) -> GPForceModels:
        """Fit each output dimension; F has shape (M, n_outputs)."""
        F = _as_array(f"{self.key}.F", F, 2)
        if F.shape[1] != self.n_outputs:
            raise ConfigError(f"{self.key}.F", f"must have {self.n_outputs} columns, got {F.shape}")
        for j, m in enumerate(self.models):
            m.fit(X, F[:, j])
        return self

    def predict(self, X: Any) -> tuple[np.ndarray, np.ndarray]:
        """Means and latent variances, each of shape (N, n_outputs)."""
        out = [m.predict(X) for m in self.models]
        return np.column_stack([o[0] for o in out]), np.column_stack([o[1] for o in out])

    def casadi_functions(self) -> dict[str, ca.Function]:
        """Stacked casadi functions: "mean"/"var" x -> (n_outputs,), "grad" x -> (n_outputs, d)."""
        for m in self.models:
            m._check_fitted()
        x = ca.MX.sym("x", self.models[0]._d)
        exprs = [m._casadi_exprs(x) for m in self.models]
        mu = ca.vertcat(*[e[0] for e in exprs])
        var = ca.vertcat(*[e[1] for e in exprs])
        return {
            "mean": ca.Function("gp_mean", [x], [mu], ["x"], ["mu"]),
            "var": ca.Function("gp_var", [x], [var], ["x"], ["var"]),
            "grad": ca.Function("gp_grad", [x], [ca.jacobian(mu, x)], ["x"], ["dmu_dx"]),
        }
