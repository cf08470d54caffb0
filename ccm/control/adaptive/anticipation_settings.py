"""The ``anticipation`` block of the anticipating controller (seed A §3.3-3.5), as typed fields.

Each field is a config key, checked as declared (:mod:`ccm.core.fields`); what each one does
is in :class:`ccm.control.adaptive.anticipation.AnticipatoryAVIC`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ccm.control.adaptive.transition import check_kinds
from ccm.core.errors import check_nonneg, check_positive
from ccm.core.fields import checked, field_values, unchecked


def _block(key: str, value: Any) -> dict[str, Any]:
    return dict(value or {})


@dataclass(frozen=True)
class AnticipationSettings:
    """Region C, blends, K*, the plan's sampling, the robot's noise and the contact rules."""

    sigma_scale: float = checked(check_positive, 3.0)  # region C at this Mahalanobis radius
    min_region_radius_m: float = checked(check_nonneg, 0.0)  # m, floor on C's semi-axes
    blend_s: float = checked(check_positive, 0.2)  # s, T of Eq. 10 and Eq. 11's changes
    k_collision: float | None = checked(check_positive, None)  # N/m, K* of Eq. 8 (None: K_free)
    path_dt: float = checked(check_positive, 0.005)  # s, sampling of the plan for p_c
    init_noise_std: Any = checked(unchecked, 0.06)  # m, the vision stand-in's noise
    init_std: Any = checked(unchecked, None)  # m, initial belief std (None: the noise's)
    use_kinds: tuple[str, ...] = checked(check_kinds, ("collision", "impactless"))
    stall_fraction: float = checked(check_positive, 0.2)
    stall_lookback_s: float = checked(check_nonneg, 0.05)  # s
    stall_travel_m: float = checked(check_positive, 0.003)  # m
    detection_noise_std: float = checked(check_nonneg, 0.0)  # m per axis
    transition_feedforward: tuple[str, ...] = checked(check_kinds, ())
    association_gate: float = checked(check_positive, 5.0)  # σ
    approach_cos_min: float = checked(check_nonneg, 0.5)
    force_along_cos: float = checked(check_nonneg, 0.5)
    map: dict[str, Any] = checked(_block, factory=dict)  # ContactMap arguments
    collisions: dict[str, Any] = checked(_block, factory=dict)  # CollisionDetector arguments

    @classmethod
    def from_mapping(cls, cfg: Any, key: str) -> AnticipationSettings:
        return cls(**field_values(cls, cfg, key)[0])
