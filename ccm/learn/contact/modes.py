"""Contact-mode detection: the incremental mode classifier (seed A §3.2, Algorithm 1).

Seed A (Sidhik et al.) §3.2 "Detecting contact modes" and Algorithm 1: a change of contact mode
shows as a sudden, significant change in the force-torque measurements (Algorithm 1, line 2).
The robot then switches to high stiffness, collects a batch of feature vectors and classifies
it against the modes seen so far with BIRCH (Zhang et al. 1997, via scikit-learn): the fraction
of the batch assigned to a mode's clusters is the confidence in that mode; if the best
confidence reaches a threshold the mode is known (its clusters are revised with the batch),
otherwise a new mode is created (Algorithm 1, lines 4-7).

:class:`ModeClassifier` is ``detect_classify_mode()`` of Algorithm 1, line 4, over
``sklearn.cluster.Birch(n_clusters=None)``. The trigger and the features it classifies are
:mod:`ccm.learn.contact.mode_features`; neither imports a simulator or a controller.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ccm.core.errors import (
    ConfigError,
    check_finite,
    check_int_positive,
    check_positive,
)


@dataclass(frozen=True)
class ModeDecision:
    """Outcome of one :meth:`ModeClassifier.classify` call.

    Attributes:
        mode: Mode id (0, 1, ...), existing or newly created.
        is_new: Whether ``mode`` was created by this call.
        confidence: Fraction of the batch assigned to the best existing mode (0 if there was
            none).
        second_confidence: Fraction assigned to the second-best existing mode (0 if none).
        counts: Batch points per existing mode id before the update; key ``-1`` counts points
            that fell in no mode's clusters. Modes with no points are left out.
    """

    mode: int
    is_new: bool
    confidence: float
    second_confidence: float
    counts: dict[int, int] = field(default_factory=dict)


class ModeClassifier:
    """Incremental contact-mode classifier over BIRCH (seed A §3.2, Algorithm 1, lines 4-7).

    Each mode owns its own ``sklearn.cluster.Birch(n_clusters=None, threshold=threshold)``,
    so the subcluster -> mode mapping is by construction. (One shared Birch would need an
    index mapping over ``subcluster_centers_``, whose order changes when a tree node splits,
    and Birch may absorb a "new" batch into old subclusters, leaving a new mode with none.)
    Per-mode point counts are kept here, not read from Birch internals.

    Rule for a batch of N feature vectors (N >= ``min_batch``):

    1. Each point is assigned to the mode of its nearest subcluster centre (over all modes)
       if that centre is within ``threshold`` (Euclidean, feature units); else to none.
    2. ``confidence`` = largest fraction of the batch assigned to one mode (ties -> lowest id).
    3. If ``confidence >= confidence_threshold``: known mode. Its Birch is ``partial_fit``
       with the batch points not claimed by another mode (so clusters follow slow drift,
       but one mode never grows into another's clusters).
    4. Else: new mode id ``n_modes`` with a fresh Birch, ``partial_fit`` with the batch points
       claimed by no mode (or the whole batch if every point was claimed, e.g. one split
       between two known modes), so new clusters do not sit on old ones. The very first
       batch is always mode 0, new.

    Args:
        threshold: Birch threshold and assignment radius, in feature units, > 0.
        confidence_threshold: Minimum fraction for a known mode, in (0, 1].
        min_batch: Minimum batch size, >= 1.
        branching_factor: Birch branching factor, >= 2.
        key: Configuration key used as the prefix of error messages.

    Raises:
        ConfigError: On an invalid argument, named ``f"{key}.<arg>"``.
    """

    def __init__(
        self,
        threshold: float,
        confidence_threshold: float,
        min_batch: int,
        branching_factor: int = 50,
        key: str = "controller.modes.classifier",
    ) -> None:
        self.key = key
        self.threshold = check_positive(f"{key}.threshold", threshold)
        c = check_finite(f"{key}.confidence_threshold", confidence_threshold)
        if not 0.0 < c <= 1.0:
            raise ConfigError(f"{key}.confidence_threshold", f"must be in (0, 1], got {c!r}")
        self.confidence_threshold = c
        self.min_batch = check_int_positive(f"{key}.min_batch", min_batch)
        self.branching_factor = check_int_positive(f"{key}.branching_factor", branching_factor)
        if self.branching_factor < 2:
            raise ConfigError(f"{key}.branching_factor", f"must be >= 2, got {branching_factor!r}")
        self.n_features_in_: int | None = None
        self._birches: list[Any] = []
        self._counts: list[int] = []

    @property
    def n_modes(self) -> int:
        """Number of modes created so far."""
        return len(self._birches)

    @property
    def mode_counts_(self) -> dict[int, int]:
        """Number of points fitted into each mode's clusters."""
        return dict(enumerate(self._counts))

    def mode_centres(self, mode: int) -> np.ndarray:
        """Subcluster centres of ``mode``, shape (k, n_features)."""
        if isinstance(mode, bool) or not isinstance(mode, int | np.integer):
            raise ConfigError(f"{self.key}.mode", f"must be an integer, got {mode!r}")
        if not 0 <= mode < self.n_modes:
            raise ConfigError(f"{self.key}.mode", f"must be in [0, {self.n_modes}), got {mode}")
        return np.array(self._birches[mode].subcluster_centers_, dtype=float)

    def _new_birch(self) -> Any:
        from sklearn.cluster import Birch  # lazy: sklearn import costs ~0.85 s

        bf, t = self.branching_factor, self.threshold
        return Birch(n_clusters=None, threshold=t, branching_factor=bf, compute_labels=False)

    def _check_batch(self, batch: Any) -> np.ndarray:
        k = f"{self.key}.batch"
        try:
            x = np.asarray(batch, dtype=float)
        except (TypeError, ValueError):
            raise ConfigError(k, "must be a 2-D array of numbers") from None
        if x.ndim != 2 or x.shape[1] < 1:
            raise ConfigError(k, f"must be a 2-D array (N, d), got shape {x.shape}")
        if x.shape[0] < self.min_batch:
            raise ConfigError(k, f"needs >= {self.min_batch} rows (min_batch), got {x.shape[0]}")
        if not np.all(np.isfinite(x)):
            raise ConfigError(k, "must be finite (features out of contact are NaN)")
        if self.n_features_in_ is not None and x.shape[1] != self.n_features_in_:
            raise ConfigError(k, f"must have {self.n_features_in_} columns, got {x.shape[1]}")
        return x

    def assign(self, batch: np.ndarray) -> np.ndarray:
        """Mode id of each row of ``batch`` (N, d) by rule step 1; -1: within no mode's radius."""
        x = self._check_batch(batch)
        if self.n_modes == 0:
            return np.full(x.shape[0], -1, dtype=int)
        centres = [np.asarray(b.subcluster_centers_, dtype=float) for b in self._birches]
        owner = np.concatenate([np.full(len(c), m, dtype=int) for m, c in enumerate(centres)])
        allc = np.concatenate(centres, axis=0)
        d2 = ((x[:, None, :] - allc[None, :, :]) ** 2).sum(axis=2)
        j = np.argmin(d2, axis=1)
        near = d2[np.arange(x.shape[0]), j] <= self.threshold**2
        return np.where(near, owner[j], -1)

    def classify(self, batch: np.ndarray) -> ModeDecision:
        """Classify a batch as a known or new mode and update the clusters (Algorithm 1).

        Args:
            batch: Feature vectors from :func:`mode_features`, shape (N, d), N >= min_batch.

        Returns:
            The decision; the classifier state is updated as described in the class rule.

        Raises:
            ConfigError: ``f"{key}.batch"`` on a misshaped, too small or non-finite batch.
        """
        x = self._check_batch(batch)
        labels = self.assign(x)
        n = x.shape[0]
        per_mode = np.bincount(labels[labels >= 0], minlength=self.n_modes)
        counts = {int(m): int(c) for m, c in enumerate(per_mode) if c > 0}
        if np.any(labels < 0):
            counts[-1] = int(np.sum(labels < 0))
        order = sorted(range(self.n_modes), key=lambda m: (-per_mode[m], m))
        conf = float(per_mode[order[0]]) / n if order else 0.0
        second = float(per_mode[order[1]]) / n if len(order) > 1 else 0.0
        if order and conf >= self.confidence_threshold:
            mode = order[0]
            pts = x[(labels == mode) | (labels < 0)]
            self._birches[mode].partial_fit(pts)
            self._counts[mode] += int(pts.shape[0])
            return ModeDecision(mode, False, conf, second, counts)
        pts = x[labels < 0] if np.any(labels < 0) else x
        birch = self._new_birch()
        birch.partial_fit(pts)
        self._birches.append(birch)
        self._counts.append(int(pts.shape[0]))
        self.n_features_in_ = x.shape[1]
        return ModeDecision(self.n_modes - 1, True, conf, second, counts)

    def state_dict(self) -> dict[str, Any]:
        """JSON-safe state: settings, and per mode its subcluster centres and point count."""
        return {
            "format": "ccm.modes.ModeClassifier/1",
            "settings": {
                "threshold": self.threshold,
                "confidence_threshold": self.confidence_threshold,
                "min_batch": self.min_batch,
                "branching_factor": self.branching_factor,
                "key": self.key,
            },
            "n_features": self.n_features_in_,
            "modes": [
                {"id": m, "count": self._counts[m], "centres": self.mode_centres(m).tolist()}
                for m in range(self.n_modes)
            ],
        }

    @classmethod
    def from_state_dict(cls, data: Mapping[str, Any], key: str | None = None) -> ModeClassifier:
        """Rebuild a classifier from :meth:`state_dict` output.

        Each mode's Birch is rebuilt by ``partial_fit`` of its stored subcluster centres
        (Birch's CF tree is not public API). Counts and centres are restored; stored centres
        closer than 2 x threshold may merge in the rebuilt tree, so decisions on points far
        inside or far outside the mode clusters are unchanged, but a point at the edge of
        a cluster's radius may be assigned differently.

        Args:
            data: Output of :meth:`state_dict` (e.g. after a JSON round trip).
            key: Error-message prefix; ``None`` uses the stored key.

        Raises:
            ConfigError: On malformed data, named ``f"{key}.<arg>"`` or
                ``f"{key}.from_state_dict..."``.
        """
        try:
            s = dict(data["settings"])
            key = key if key is not None else str(s.get("key", "controller.modes.classifier"))
            modes, n_features = list(data["modes"]), data["n_features"]
        except (KeyError, TypeError) as e:
            k = key if key is not None else "controller.modes.classifier"
            raise ConfigError(f"{k}.from_state_dict", f"malformed state: {e!r}") from None
        args = (s.get(a) for a in ("threshold", "confidence_threshold", "min_batch"))
        out = cls(*args, s.get("branching_factor", 50), key=key)
        for i, rec in enumerate(modes):
            k = f"{key}.from_state_dict.modes[{i}]"
            try:
                centres = np.asarray(rec["centres"], dtype=float)
                count = check_int_positive(f"{k}.count", rec["count"])
                ok = rec["id"] == i
            except (KeyError, TypeError, ValueError) as e:
                raise ConfigError(k, f"malformed mode record: {e!r}") from None
            if not ok:
                raise ConfigError(f"{k}.id", f"must be {i}, got {rec['id']!r}")
            if centres.ndim != 2 or len(centres) == 0 or centres.shape[1] != n_features:
                raise ConfigError(f"{k}.centres", f"must be (k, {n_features}) with k >= 1")
            if not np.all(np.isfinite(centres)):
                raise ConfigError(f"{k}.centres", "must be finite")
            birch = out._new_birch()
            birch.partial_fit(centres)
            out._birches.append(birch)
            out._counts.append(count)
        out.n_features_in_ = None if not modes else int(n_features)
        return out
