"""Contact-mode detection and one forward model per mode (seed A §3.2, Algorithm 1).

:class:`ContactModes` is a part that the controller of Eq. 4a–4c
(:class:`ccm.control.adaptive.avic.AVIC` with a ``modes`` block) holds as its ``modes``
member: the controller then runs with the forward model of the *current contact mode*.
Algorithm 1 of seed A adds, every control step:

1. **Trigger** (line 2): a sudden change of a wrench feature (:class:`TransitionTrigger`),
   or first sliding after (re)gaining contact, starts a transition.
2. **K_max and a batch** (line 3): from the trigger on the stiffness is K_max and feature
   vectors (Eq. 7, :func:`mode_features`) are collected until the batch is full.
3. **Classify** (line 4): BIRCH (:class:`ModeClassifier`) gives the best mode, its confidence
   and the second-best; below the confidence threshold a new mode is created (lines 5–7).
4. **Use and revise the mode's model** (line 9): the chosen mode's IGMM is revised with the
   batch's samples and then every step, and drives λ (Eq. 4c) as in plain AVIC.

What the controller uses. Only the Observation and the target: the normal force R is the
measured force along the commanded force direction of the hybrid law (Eq. 1 u_fc), the
friction force F of Eq. 7 is the measured force in the plane normal to it, and "sliding" means
the measured velocity in that plane exceeds ``sliding_speed``. Without a force-controlled
direction, or with R below ``min_normal_force``, the tool is taken to be out of contact: mode
−1, served by a free-space model.

Evidence rule (ccm's choice; seed A §4.3 says a new mode's model is built "while operating
under high stiffness" without saying for how long), ``evidence``:

* ``samples``: a mode's model drives λ only once it has been revised with at least
  ``min_mode_samples`` samples; before that K_max is held. A known mode has them already, a
  new one must gather them, so the rule itself makes a new mode's high-stiffness period
  longer (by ``min_mode_samples`` control steps). ``min_mode_samples: 0`` leaves the
  release to Eq. 4c alone.
* ``prequential`` (issue #38): the evidence is the data's. After each mode decision K_max is
  held until the mode's model has predicted ``evidence_window`` consecutive samples, each
  before it learned that sample, with an error ε_t below Eq. 4c's midpoint ε₀ (the level at
  which Eq. 4c itself calls a prediction good, λ = ½). A known mode's model can do that at
  once; a new one only once it has learned the surface, however many samples that takes.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ccm.control.base import check_state_keys
from ccm.core.errors import (
    ConfigError,
    check_choice,
    check_int_nonneg,
    check_int_positive,
    check_keys,
    check_nonneg,
    check_positive,
)
from ccm.core.fields import checked, field_values, one_of
from ccm.core.filters import first_order_alpha
from ccm.core.types import Observation, TargetSample
from ccm.learn.contact.mode_features import FEATURE_KINDS, TransitionTrigger, feature_vector
from ccm.learn.contact.modes import ModeClassifier
from ccm.learn.mixtures.forward_model import make_forward_model

TRIGGER_SIGNALS = ("tangential_force", "feature")
#: what ends a mode's high-stiffness period besides Eq. 4c (module docstring)
EVIDENCE_RULES = ("samples", "prequential")
FREE = -1  # mode id of "no contact mode" (free space, or not yet classified)


def _block(allowed: tuple[str, ...]) -> Callable[[str, Any], dict[str, Any]]:
    """A check: a sub-block mapping (None: empty) with only ``allowed`` keys."""

    def check(key: str, value: Any) -> dict[str, Any]:
        if value is None:
            return {}
        if not isinstance(value, Mapping):
            raise ConfigError(key, f"must be a mapping, got {type(value).__name__}")
        check_keys(key, value, allowed)
        return dict(value)

    return check


def _trigger(key: str, value: Any) -> dict[str, Any]:
    """``trigger``: ``signal`` (tangential_force | feature), ``threshold`` > 0, and the
    :class:`TransitionTrigger` arguments ``window`` and ``refractory_steps``."""
    trig = _block(("signal", "threshold", "window", "refractory_steps"))(key, value)
    signal = check_choice(f"{key}.signal", trig.pop("signal", "feature"), TRIGGER_SIGNALS)
    thr = check_positive(f"{key}.threshold", trig.pop("threshold", 0.07))
    return {"signal": signal, "args": {"threshold_N": thr, "window": 50, **trig}}


@dataclass(frozen=True)
class ModeSettings:
    """The ``modes`` block of Algorithm 1 (meanings: :class:`ContactModes`), as typed fields."""

    feature: str = checked(one_of(FEATURE_KINDS), "force_ratio")
    trigger: dict[str, Any] = checked(_trigger, factory=lambda: _trigger("modes.trigger", None))
    batch_size: int = checked(check_int_positive, 100)
    classifier: dict[str, Any] = checked(
        _block(("threshold", "confidence_threshold", "branching_factor")), factory=dict
    )
    min_normal_force: float = checked(check_nonneg, 1.0)  # N
    sliding_speed: float = checked(check_nonneg, 0.01)  # m/s
    min_mode_samples: int = checked(check_int_nonneg, 0)
    evidence: str = checked(one_of(EVIDENCE_RULES), "samples")
    evidence_window: int = checked(check_int_positive, 100)  # samples (``prequential``)
    contact_loss_steps: int = checked(check_int_nonneg, 20)
    feature_lowpass_hz: float | None = checked(check_positive, None)  # Hz
    settle_time_constants: float = checked(check_nonneg, 3.0)

    @classmethod
    def from_mapping(cls, cfg: Any, key: str) -> ModeSettings:
        return cls(**field_values(cls, cfg, key)[0])


class ContactModes:
    """Algorithm 1 of seed A (§3.2): contact-mode detection and one forward model per mode,
    held by :class:`ccm.control.adaptive.avic.AVIC` as its ``modes`` member.

    Args:
        modes: Mode-detection settings (all validated, errors name ``controller.modes.*``):
            ``feature`` (``force_ratio`` = Eq. 7 ``‖F‖/R`` or ``torque_force_ratio``),
            ``trigger`` (``signal``: ``tangential_force`` [N] or ``feature`` [feature
            units]; ``threshold``; ``window`` [steps]), ``batch_size`` [samples],
            ``classifier`` (:class:`ModeClassifier` arguments except ``min_batch``),
            ``min_normal_force`` [N], ``sliding_speed`` [m/s], ``evidence`` (``samples``
            or ``prequential``, module docstring), ``min_mode_samples``, ``evidence_window``,
            ``contact_loss_steps`` (steps below ``min_normal_force`` that mean contact is
            lost; shorter dips, e.g. a force-loop transient, keep the mode),
            ``feature_lowpass_hz`` (first-order low-pass on ‖F_t‖, ‖τ‖ and R before Eq. 7,
            restarted on each contact; ``None`` = raw samples; a batch then starts three
            time constants after its trigger).
        free_model: the free-space forward model (mode −1), the controller's own.
        forward_model: the ``forward_model`` block each new mode's model is built from.
        key: the controller's config key (errors name ``<key>.modes.*``).
    """

    def __init__(
        self,
        modes: Mapping[str, Any] | None,
        free_model: Any,
        forward_model: Mapping[str, Any] | None = None,
        key: str = "controller",
    ) -> None:
        self.key = f"{key}.modes"
        self.mcfg = mcfg = ModeSettings.from_mapping(modes, self.key)
        self._fm_cfg = dict(forward_model or {})
        self._fm_key = f"{key}.forward_model"
        # learned state, kept across trials (reset() does not clear it)
        self.classifier = ModeClassifier(
            **{"threshold": 0.05, "confidence_threshold": 0.6, **mcfg.classifier},
            min_batch=mcfg.batch_size,
            key=f"{self.key}.classifier",
        )
        self.make_trigger()  # validates the trigger settings now, not at the first step
        self.models: dict[int, Any] = {FREE: free_model}
        self.samples: dict[int, int] = {FREE: 0}
        self.mode = FREE
        self.model = free_model
        self._streak = 0

    def make_trigger(self) -> TransitionTrigger:
        """A fresh :class:`TransitionTrigger` from the configured settings."""
        args = dict(self.mcfg.trigger["args"])
        args.setdefault("refractory_steps", self.mcfg.batch_size)
        return TransitionTrigger(**args, key=f"{self.key}.trigger")

    def reset(self, control_dt: float) -> None:
        """A new trial: free space, no batch, a fresh trigger (the modes stay)."""
        mcfg = self.mcfg
        self.trigger = self.make_trigger()
        self.mode, self.model = FREE, self.models[FREE]
        self.switched = False  # whether the last before_step changed the mode
        self._collecting = False
        self._streak = 0  # consecutive good predictions of the current mode's model
        self._pending = False  # in contact but not yet classified
        self._batch: list[np.ndarray] = []
        self._replay: list[tuple[np.ndarray, np.ndarray]] = []
        self._conf = (math.nan, math.nan)
        self._off = mcfg.contact_loss_steps + 1  # steps since R last exceeded min_normal_force
        self._lp: tuple[float, ...] | None = None  # low-passed (‖F_t‖, ‖τ‖, R)
        hz = mcfg.feature_lowpass_hz
        self._alpha = 1.0 if hz is None else first_order_alpha(control_dt, hz)
        # a batch starts settle_time_constants filter time constants (3: 95 % of a step) after
        # its trigger, so it holds the new surface's ratio, not the filter's ramp from the old one
        self.settle_steps = (
            0
            if hz is None
            else math.ceil(mcfg.settle_time_constants / (2.0 * math.pi * hz) / control_dt)
        )
        self._settle = 0
        self.last_signals = self._signals(0.0, 0.0, 0.0)

    def _signals(self, trig: float, event: float, collecting: float) -> dict[str, float]:
        return {
            "mode": float(self.mode),
            "mode_trigger": trig,
            "mode_event": event,
            "mode_confidence": self._conf[0],
            "mode_second_confidence": self._conf[1],
            "mode_collecting": collecting,
            "n_modes": float(self.classifier.n_modes),
        }

    # ------------------------------------------------------------------ Algorithm 1

    def contact_state(
        self, obs: Observation, target: TargetSample
    ) -> tuple[bool, np.ndarray | None, float]:
        """(in contact, feature vector while sliding else None, ‖F_t‖ [N]) from the measured
        wrench and velocity and the commanded force direction n."""
        n = target.force_dir
        if n is None:
            self._lp = None
            return False, None, 0.0
        f, v, nl = obs.force.tolist(), obs.lin_vel.tolist(), n.tolist()  # plain floats: 2-3 entries
        fn = _dot(f, nl)
        r = -fn  # the surface pushes back against the commanded force direction
        if r < self.mcfg.min_normal_force:
            self._lp = None
            return False, None, 0.0
        # Eq. 7 uses the friction force: the measured force in the plane normal to n
        tq = obs.torque.tolist()
        raw = (math.sqrt(max(_dot(f, f) - fn * fn, 0.0)), math.sqrt(_dot(tq, tq)), r)
        if self._lp is None or self._alpha >= 1.0:
            self._lp = raw
        else:
            a = self._alpha
            self._lp = tuple(y + a * (x - y) for x, y in zip(raw, self._lp, strict=True))
        f_t, tau, r = self._lp
        vn = _dot(v, nl)
        if _dot(v, v) - vn * vn < self.mcfg.sliding_speed**2:  # |v_t|² = |v|² − (v·n)²
            return True, None, f_t
        return True, feature_vector(f_t, tau, r, self.mcfg.feature), f_t

    def before_step(self, obs: Observation, target: TargetSample) -> None:
        """Algorithm 1, lines 2–7, on this step's measurements (sets :attr:`switched`)."""
        self.switched = False
        trig = event = 0.0
        contact, feat, f_t = self.contact_state(obs, target)
        self._off = 0 if contact else self._off + 1
        if self._off > self.mcfg.contact_loss_steps:  # out of contact for long enough
            if self.mode != FREE or self._pending or self._collecting:
                self._switch(FREE)
                self._pending = self._collecting = False
                self.trigger.reset()
        elif contact and self.mode == FREE and not self._collecting:
            self._pending = True  # contact made: K_max until the first batch is classified
        if feat is None and contact and self._batch:
            self._batch, self._replay = [], []  # a batch is one stretch of sliding: restart it
        if feat is not None:  # sliding in contact: Eq. 7 is a friction estimate
            x = float(feat[-1]) if self.mcfg.trigger["signal"] == "feature" else f_t
            fired = self.trigger.update(x)
            if not self._collecting and (fired or self._pending):
                self._collecting, self._pending = True, False
                self._batch, self._replay = [], []
                self._settle = self.settle_steps
                trig = 1.0
            if self._collecting and self._settle > 0:
                self._settle -= 1  # the low-pass is still moving between the two surfaces
            elif self._collecting:
                self._batch.append(feat)
                if len(self._batch) >= self.mcfg.batch_size:
                    event = self._decide()
        self.last_signals = self._signals(trig, event, float(self._collecting))

    def _decide(self) -> float:
        """Classify the batch (Algorithm 1, line 4); 1.0 = known mode, 2.0 = new mode."""
        decision = self.classifier.classify(np.array(self._batch))
        if decision.is_new:
            self.models[decision.mode] = make_forward_model(dict(self._fm_cfg), self._fm_key)
            self.samples[decision.mode] = 0
        self._conf = (decision.confidence, decision.second_confidence)
        self._switch(decision.mode)
        replay, self._batch, self._replay = self._replay, [], []
        self._collecting = False
        for s_prev, d in replay:  # the batch's samples belong to the decided mode
            self.learn(s_prev, d)
        return 2.0 if decision.is_new else 1.0

    def _switch(self, mode: int) -> None:
        """Make ``mode``'s model current (the controller then forgets the previous model's
        predictions and restarts λ from K_max)."""
        self.mode = mode
        self.model = self.models[mode]
        self.switched = True
        self._streak = 0

    def observe_error(self, err: float, eps0: float) -> None:
        """One prequential prediction error ε_t [N] of the current mode's model (predicted
        before it learned the sample) against Eq. 4c's midpoint ε₀ (``prequential``)."""
        self._streak = self._streak + 1 if err < eps0 else 0  # NaN ε₀: no evidence

    def learn(self, s_prev: np.ndarray, d_now: np.ndarray) -> None:
        """Revise the current mode's model; during a batch, keep the sample for the decided
        mode (it is not known yet) and revise no model."""
        if self._collecting:
            self._replay.append((s_prev.copy(), d_now.copy()))
            return
        if self._pending:
            return  # in contact, mode unknown: no model owns these samples
        self.model.update(s_prev, d_now)
        self.samples[self.mode] += 1

    def hold_k_max(self) -> bool:
        """K_max while a transition is being confirmed (Algorithm 1, line 3), while the mode is
        unknown, and until the current mode's model has the evidence of ``evidence``
        (``min_mode_samples`` samples, or ``evidence_window`` good predictions in a row)."""
        if self._collecting or self._pending:
            return True
        if self.mode == FREE:
            return False
        if self.mcfg.evidence == "prequential":
            return self._streak < self.mcfg.evidence_window
        return self.samples[self.mode] < self.mcfg.min_mode_samples

    def end_trial(self) -> None:
        """Every mode's model gets the end-of-trial hook (modes persist across trials)."""
        for model in self.models.values():
            model.end_trial()

    # ------------------------------------------------------------------ learned state

    def state_dict(self) -> dict[str, Any]:
        """The mode classifier, and per mode (``-1`` = free space) its forward model and the
        number of samples it has been revised with (``min_mode_samples``). Batches, the
        trigger and the current mode are per-trial state."""
        return {
            "classifier": self.classifier.state_dict(),
            "modes": [
                {"mode": m, "samples": self.samples[m], "forward_model": fm.state_dict()}
                for m, fm in sorted(self.models.items())
            ],
        }

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state_dict` output. Classifier and forward-model settings stay
        this config's; the modes, their clusters, models and sample counts come from
        ``state``. Nothing changes unless all of it is accepted; the mode becomes free space.

        Raises:
            ValueError, TypeError, KeyError: on a malformed or mismatched state.
        """
        check_state_keys(state, ("classifier", "modes"))
        settings = self.classifier.state_dict()["settings"]
        classifier = ModeClassifier.from_state_dict({**state["classifier"], "settings": settings})
        models: dict[int, Any] = {}
        samples: dict[int, int] = {}
        for rec in state["modes"]:
            check_state_keys(rec, ("mode", "samples", "forward_model"))
            mode = rec["mode"]
            if isinstance(mode, bool) or not isinstance(mode, int) or mode in models:
                raise ValueError(f"mode ids must be distinct integers, got {mode!r}")
            fm = make_forward_model(dict(self._fm_cfg), self._fm_key)
            fm.load_state_dict(rec["forward_model"])
            models[mode] = fm
            samples[mode] = check_int_nonneg(f"modes[{mode}].samples", rec["samples"])
        n_features = len(feature_vector(1.0, 1.0, 1.0, self.mcfg.feature))
        if classifier.n_features_in_ not in (None, n_features):
            raise ValueError(
                f"the saved modes have {classifier.n_features_in_} features, "
                f"modes.feature={self.mcfg.feature} has {n_features}"
            )
        expected = [FREE, *range(classifier.n_modes)]
        if sorted(models) != expected:
            raise ValueError(
                f"modes {sorted(models)} do not match the classifier's {expected} (-1 = free space)"
            )
        self.classifier, self.models, self.samples = classifier, models, samples
        self._switch(FREE)


def _dot(a: list[float], b: list[float]) -> float:
    """``a · b`` of two short lists of floats, summed in order (unrolled up to 3 entries)."""
    if len(a) == 3:
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    if len(a) == 2:
        return a[0] * b[0] + a[1] * b[1]
    return sum(x * y for x, y in zip(a, b, strict=True))
