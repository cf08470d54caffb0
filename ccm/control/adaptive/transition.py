"""The transition-phase controller of seed A §3.4 (Eq. 8), used by
:mod:`ccm.control.adaptive.anticipation`.

    u = K* Δx + D* Δẋ + u_ff + H                                           (8)

Seed A: the transition-phase controller "has the same structure as our base (variable
impedance) controller (i.e., Equation 4a)"; only K* and D* differ (K* = ``k_collision`` before
a collision, K_max around an impact-less transition). So u_ff is the base's feed-forward
λ Ŵ of Eq. 4a, the forward model's predicted wrench weighted by its accuracy, exactly as the
base controller applied it in the same step
(:attr:`ccm.control.adaptive.avic.AVIC.last_feedforward`:
zero while Algorithm 1 holds K_max, where λ = 0). H is the robot's own compensation (the
simulator's inverse dynamics) plus Λ ẍ_d (or m ẍ_d) when ``inertia_feedforward`` is on. The hybrid
force loop u_fc of Eq. 1 is kept where the caller says so (``keep_force_loop``): across the
motion (a press on the table while sliding into a wall), not along it.

``controller.anticipation.transition_feedforward`` lists the kinds of transition controller
that add u_ff. It is empty by default (measured, issue #17 item 5, experiments/h4.md):

* At a collision, ccm's one-step forward model predicts the rising contact force almost
  exactly, so λ stays near 1, and with ``ff_direction: along_motion`` Ŵ points into the
  compliant contact the tool is sinking into: u_ff cancels the contact's reaction, a positive
  feedback (h4_impactless seed 0: a 128 N table impact instead of 24 N; Eq. 9 then learned a
  near-zero approach speed and trials 2-3 ran into the time limit).
* Around an impact-less transition Algorithm 1 resets λ to 0 when it decides the new mode,
  so u_ff = λ Ŵ drops by the whole predicted friction force in one step. Without u_ff the
  K_max controller hides that drop from the command; with it the drop passes through (peak
  ‖a‖ at the switches in trials 2-3 0.45-0.59 m/s² instead of 0.05, seeds 0-4).

Seed A also sets K* = K_max "the maximum allowed values of the adaptive variable impedance
controller" for impact-less transitions; in Eq. 4b K_p = K_max means λ = 0, and then Eq. 4a's
feed-forward λ Ŵ is zero too.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ccm.control.loop import impedance_term
from ccm.core.errors import ConfigError
from ccm.core.types import Observation, TargetSample

KINDS = ("collision", "impactless")


def check_kinds(key: str, value: Any) -> tuple[str, ...]:
    """A list of contact kinds (``collision``, ``impactless``), as a tuple."""
    if (
        isinstance(value, str)
        or not isinstance(value, Sequence)
        or any(k not in KINDS for k in value)
    ):
        raise ConfigError(key, f"must be a list of: {', '.join(KINDS)}; got {value!r}")
    return tuple(value)


def transition_force(
    obs: Observation,
    target: TargetSample,
    gains: tuple[float, float | np.ndarray],
    mass_kg: float | np.ndarray,
    inertia_feedforward: bool,
    force_loop: np.ndarray | None,
    feedforward: np.ndarray | None,
) -> np.ndarray:
    """Eq. 8's force for stiffness and damping ``gains`` = (K*, D*).

    Args:
        obs: this step's observation.
        target: this step's target.
        gains: K* [N/m] and D* [N s/m] (a scalar, or (n, n) for the arm's Λ(q)).
        mass_kg: as :func:`ccm.control.loop.impedance_term` (the mass or Λ(q),
            :meth:`ccm.control.loop.HybridLoop.inertia_of`).
        inertia_feedforward: as :func:`ccm.control.loop.impedance_term`.
        force_loop: the base's force-loop force u_fc this step, replacing the impedance
            along the commanded force direction; None keeps the impedance there.
        feedforward: the base's λ Ŵ this step, subtracted as in Eq. 4a (u_ff); None: none.
    """
    u = impedance_term(obs, target, gains[0], gains[1], mass_kg, inertia_feedforward)
    d = target.force_dir
    if force_loop is not None and d is not None:
        u = u - d * float(d @ u) + force_loop
    if feedforward is not None:
        u = u - feedforward
    return u
