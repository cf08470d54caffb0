"""The mixture buffers of an :class:`ccm.learn.mixtures.igmm.IGMM` and what is read from them.

:class:`MixtureBuffers` is the base of ``IGMM``: the fitted attributes (components, priors
p(j) = sp_j / sum_q sp_q of seed A Eq. 5, ages, event counters) as copies of the preallocated
buffers the numba kernels update (laid out as :mod:`ccm.learn.mixtures._igmm_layout`
describes), and the three operations on the buffers as a whole: forget every component
(:meth:`~MixtureBuffers.reset`), hand the buffers to a control loop that calls the kernels
itself (:meth:`~MixtureBuffers.kernel_buffers`) and set restored components
(:meth:`~MixtureBuffers.restore`). ``IGMM`` allocates the buffers from its settings and learns
into them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Self

import numpy as np

from ccm.learn.mixtures import _igmm_kernels as _k
from ccm.learn.mixtures import _igmm_layout as _lay

__all__ = ["MixtureBuffers"]

_COUNTERS = {
    "created": _lay.I_CREATED,
    "merged": _lay.I_MERGED,
    "overflow_pruned": _lay.I_OVERFLOW_PRUNED,
    "support_pruned": _lay.I_SUPPORT_PRUNED,
    "jitter": _lay.I_JITTER,
}


class MixtureBuffers:
    """Fitted attributes and whole-buffer operations of an IGMM (the base of ``IGMM``).

    The subclass allocates the buffers (``IGMM._allocate``) before any of these is used.
    """

    _threshold: float
    _means: np.ndarray
    _covs: np.ndarray
    _chols: np.ndarray
    _comp: np.ndarray
    _sp: np.ndarray
    _age: np.ndarray
    _istate: np.ndarray
    _params: np.ndarray
    _sigma2: np.ndarray
    _work: np.ndarray

    @property
    def n_components_(self) -> int:
        """Number of live components K (0 before the first point)."""
        return int(self._istate[_lay.I_K])

    @property
    def n_seen_(self) -> int:
        """Number of points processed since construction or the last :meth:`reset`."""
        return int(self._istate[_lay.I_SEEN])

    @property
    def weights_(self) -> np.ndarray:
        """Priors p(j) = sp_j / sum_q sp_q, shape (K,) (a copy)."""
        sp = self._sp[: self.n_components_]
        return sp / sp.sum() if sp.size else sp.copy()

    @property
    def means_(self) -> np.ndarray:
        """Component means, shape (K, d) (a copy)."""
        return self._means[: self.n_components_].copy()

    @property
    def covariances_(self) -> np.ndarray:
        """Component covariances, shape (K, d, d) (a copy)."""
        return self._covs[: self.n_components_].copy()

    @property
    def support_(self) -> np.ndarray:
        """Accumulated posterior support sp_j, shape (K,) (a copy)."""
        return self._sp[: self.n_components_].copy()

    @property
    def ages_(self) -> np.ndarray:
        """Updates since creation v_j, shape (K,) (int64 copy)."""
        return self._age[: self.n_components_].astype(np.int64)

    @property
    def novelty_threshold_(self) -> float:
        """Squared Mahalanobis distance at or beyond which a point is novel."""
        return self._threshold

    @property
    def novelty_tau_(self) -> float:
        """Engel & Heinen's tau_nov equivalent to the chi-square threshold."""
        return math.exp(-0.5 * self._threshold)

    @property
    def stats_(self) -> dict[str, int]:
        """Event counters: components created, merged, pruned; factorisations jittered."""
        return {name: int(self._istate[i]) for name, i in _COUNTERS.items()}

    @property
    def version_(self) -> int:
        """Increases on every model change (GMR caches compare against it)."""
        return int(self._istate[_lay.I_VERSION])

    def reset(self) -> Self:
        """Forget all components (keeps the settings); cached GMR splits are invalidated."""
        version = int(self._istate[_lay.I_VERSION])
        stamp = int(self._istate[_lay.I_STAMP])  # stamps stay unique over the model's life
        self._istate[:] = 0
        self._istate[_lay.I_VERSION] = version + 1
        self._istate[_lay.I_STAMP] = stamp
        for arr in (self._means, self._covs, self._chols, self._comp):
            arr[...] = 0.0
        return self

    def kernel_buffers(self) -> tuple[np.ndarray, ...]:
        """The mixture buffers :func:`ccm.learn.mixtures._igmm_kernels.fit_rows` takes after the
        rows (fixed for the model's life), for a control loop that calls the kernels itself."""
        return (
            self._means, self._covs, self._chols, self._comp, self._istate, self._params,
            self._sigma2, self._work,
        )  # fmt: skip

    def restore(
        self,
        means: np.ndarray,
        covs: np.ndarray,
        support: np.ndarray,
        ages: np.ndarray,
        *,
        n_seen: int,
        stats: Mapping[str, Any],
    ) -> None:
        """Set the components (checked arrays: :mod:`ccm.learn.mixtures.igmm_io`) and the
        counters of a fresh model; ValueError if a covariance is not positive definite."""
        n = means.shape[0]
        self._means[:n] = means
        self._covs[:n] = covs
        self._sp[:n] = support
        self._age[:n] = np.floor(ages)
        bad = _k.refactor_all(n, self._covs, self._chols, self._comp, self._istate)
        if bad >= 0:
            raise ValueError(f"IGMM data: covariance {bad} is not positive definite")
        self._istate[_lay.I_K] = n
        self._istate[_lay.I_SEEN] = n_seen
        for name, i in _COUNTERS.items():
            self._istate[i] = int(stats.get(name, 0))
        self._istate[_lay.I_VERSION] = 1
