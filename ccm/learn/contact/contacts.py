"""Contact anticipation (seed A §3.3) and per-contact approach velocities (Eq. 9, §3.4.1).

* :class:`ccm.learn.contact.belief.ContactBelief` - one expected contact as a Gaussian
  N(c, P) in task space, revised across trials by a Kalman filter.
* :class:`ccm.learn.contact.approach.ApproachVelocityModel` - approach speed toward one
  collision contact: a safe low speed first, then Eq. 9 or a fitted linear impact-force
  model, below the force limit.
* :class:`ContactMap` - the contacts of one task: noisy configured positions (a stand-in for
  vision), event association, an end-of-trial hook and JSON persistence (no pickle).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ccm.core.errors import (
    ConfigError,
    check_bool,
    check_choice,
    check_finite,
    check_keys,
    check_positive,
    check_vector,
    constructor_kwargs,
)
from ccm.learn.contact.approach import ApproachVelocityModel
from ccm.learn.contact.belief import ContactBelief, std_vector

_FORMAT = "ccm.contacts.ContactMap"
_FORMAT_VERSION = 1
KINDS: tuple[str, ...] = ("collision", "impactless")
SOURCES: tuple[str, ...] = ("config", "observed")


@dataclass
class Contact:
    """One contact of a :class:`ContactMap`: its position ``belief``, ``kind`` (``"collision"``
    or ``"impactless"``, §3.3), ``name``, ``approach`` model (collisions only), ``source``
    (``"config"`` or ``"observed"``), whether it was measured in the current trial and
    ``lead``: the controller's target minus the measured contact position at the last
    measurement [m] (None before one), set by the controller that plans with it."""

    belief: ContactBelief
    kind: str
    name: str
    approach: ApproachVelocityModel | None
    source: str = "config"
    updated_this_trial: bool = False
    lead: np.ndarray | None = None


@dataclass(frozen=True)
class ContactEvent:
    """Outcome of :meth:`ContactMap.observe`: contact ``index``, whether the event created it
    (``is_new``) or corrected its belief (``updated``), and the gating distance (None if new)."""

    index: int
    is_new: bool
    updated: bool
    distance: float | None


class ContactMap:
    """Beliefs and approach models of the contacts of a task (§3.3, §3.4.1, seed A).

    Association: an event at z goes to the contact of the same kind at the smallest
    Mahalanobis distance of z under the innovation covariance P + R (what the measurement is
    expected to scatter by, measurement noise included) if it is <= ``gate``; otherwise a new
    contact is created at z with std ``new_contact_std`` (e.g. one not in the config, seen in
    trial 1). With ``once_per_trial`` a contact takes one measurement per trial: later events
    associated with it in the same trial (bounces, re-detections) are not independent
    measurements and do not update it again.

    Args:
        dim: Task-space dimension, 2 or 3.
        process_noise_std: Per-trial random walk of a contact, Q = diag(std^2), m, scalar or
            per axis (chosen 0.001: keeps P from collapsing, so a drift is still followed).
        measurement_noise_std: R = diag(std^2), m (default 0.005, a generic forward-kinematics
            error; the H4 configs use the detection chain's measured 0.11 mm,
            configs/controller/avic_anticipation.yaml).
        new_contact_std: Std of a contact first seen in a trial, m (chosen 0.05: half the
            vision error of Table 1, wide enough for the detection delay of impact-less
            transitions).
        gate: Association gate in σ units (chosen 3).
        once_per_trial: See above.
        approach: :class:`ApproachVelocityModel` arguments shared by every collision contact.
        key: Configuration key used as the prefix of error messages.
    """

    def __init__(
        self,
        dim: int,
        *,
        process_noise_std: Any = 0.001,
        measurement_noise_std: Any = 0.005,
        new_contact_std: Any = 0.05,
        gate: float = 3.0,
        once_per_trial: bool = True,
        approach: Mapping[str, Any] | None = None,
        key: str = "controller.contacts",
    ) -> None:
        self.key = key
        if isinstance(dim, bool) or dim not in (2, 3):
            raise ConfigError(f"{key}.dim", f"must be 2 or 3, got {dim!r}")
        self.dim = int(dim)
        d = self.dim
        self.process_noise_std = std_vector(f"{key}.process_noise_std", process_noise_std, d, False)
        self.measurement_noise_std = std_vector(
            f"{key}.measurement_noise_std", measurement_noise_std, d
        )
        self.new_contact_std = std_vector(f"{key}.new_contact_std", new_contact_std, d)
        self.gate = check_positive(f"{key}.gate", gate)
        self.once_per_trial = check_bool(f"{key}.once_per_trial", once_per_trial)
        k = f"{key}.approach"
        params = constructor_kwargs(ApproachVelocityModel, approach or {}, k)
        self.approach_params = ApproachVelocityModel(**params, key=k).get_params()  # validated
        self.contacts: list[Contact] = []
        self.trial = 0

    @classmethod
    def from_config(
        cls,
        expected_contacts: Sequence[Any],
        rng: np.random.Generator,
        init_noise_std: Any = 0.1,
        init_std: Any = None,
        **kwargs: Any,
    ) -> ContactMap:
        """Initial beliefs: configured positions plus Gaussian noise (a stand-in for vision).

        Args:
            expected_contacts: Each a position [x, y(, z)] (a collision) or a mapping
                ``{position, kind="collision", name="contact<i>"}``, all of one dimension.
            rng: The only source of randomness.
            init_noise_std: Std of the noise added to each position, m, scalar or per axis
                (0.1: seed A Table 1 starts 0.09-0.12 m off).
            init_std: Std of the initial beliefs, m; default ``init_noise_std`` floored at the
                measurement noise, so a belief states the error it actually has.
            **kwargs: :class:`ContactMap` arguments; ``dim`` is needed if the list is empty.
        """
        key = str(kwargs.get("key", "controller.contacts"))
        if not isinstance(rng, np.random.Generator):
            raise ConfigError(f"{key}.rng", f"must be a numpy.random.Generator, got {rng!r}")
        entries = []
        for i, e in enumerate(expected_contacts):
            k = f"{key}.expected_contacts[{i}]"
            e = dict(e) if isinstance(e, Mapping) else {"position": e}
            check_keys(k, e, ("position", "kind", "name"))
            pos = check_vector(f"{k}.position", e.get("position"), kwargs.get("dim", (2, 3)))
            kwargs.setdefault("dim", len(pos))
            kind = check_choice(f"{k}.kind", e.get("kind", "collision"), KINDS)
            entries.append((pos, kind, str(e.get("name", f"contact{i + 1}"))))
        if "dim" not in kwargs:
            raise ConfigError(f"{key}.dim", "must be given when expected_contacts is empty")
        out = cls(**kwargs)
        noise = std_vector(f"{key}.init_noise_std", init_noise_std, out.dim, False)
        std = np.maximum(noise, out.measurement_noise_std)
        if init_std is not None:
            std = std_vector(f"{key}.init_std", init_std, out.dim)
        for pos, kind, name in entries:
            mean = pos + rng.normal(0.0, 1.0, size=out.dim) * noise
            out._append(mean, std, kind, name, "config")
        return out

    def _noise_covs(self) -> tuple[np.ndarray, np.ndarray]:
        return np.diag(self.process_noise_std**2), np.diag(self.measurement_noise_std**2)

    def _append(self, mean: np.ndarray, std: np.ndarray, kind: str, name: str, src: str) -> int:
        i, k = len(self.contacts), self.key
        q, r = self._noise_covs()
        belief = ContactBelief(mean, np.diag(std**2), q, r, key=f"{k}.contacts[{i}]")
        approach = None
        if kind == "collision":
            approach = ApproachVelocityModel(**self.approach_params, key=f"{k}.approach")
        self.contacts.append(Contact(belief, kind, name, approach, src))
        return i

    @property
    def beliefs(self) -> list[ContactBelief]:
        """The position beliefs, in contact order."""
        return [c.belief for c in self.contacts]

    def _nearest(self, z: Any, kind: str | None) -> tuple[np.ndarray, float, int | None]:
        z = check_vector(f"{self.key}.z", z, self.dim)
        if kind is not None:
            check_choice(f"{self.key}.kind", kind, KINDS)
        dist, best = math.inf, None
        for i, c in enumerate(self.contacts):
            if kind is None or c.kind == kind:
                d = float(c.belief.mahalanobis(z, c.belief.cov + c.belief.R))
                dist, best = (d, i) if d < dist else (dist, best)
        return z, dist, best

    def associate(self, z: Any, gate: float | None = None, kind: str | None = None) -> int | None:
        """Index of the contact (of ``kind`` if given) nearest to z within ``gate``, or None."""
        g = self.gate if gate is None else check_positive(f"{self.key}.gate", gate)
        _, dist, i = self._nearest(z, kind)
        return i if dist <= g else None

    def observe(
        self,
        z: Any,
        kind: str = "collision",
        *,
        v_used: float | None = None,
        f_measured: float | None = None,
        expected: int | None = None,
        expected_gate: float | None = None,
    ) -> ContactEvent:
        """A contact detected at end-effector position ``z``: associate and update, or create.

        ``v_used`` and ``f_measured`` (speed and impact force of a collision), given together,
        also update that contact's :class:`ApproachVelocityModel`, unless the event is a
        repeat within the trial (``updated`` False): a bounce is no new Eq. 9 measurement.
        ``expected``: the contact the robot was anticipating when the event came (it was in
        that contact's region C); it is tried first, within the gate, so that wide early
        beliefs are not mixed up by nearest-neighbour association; ``expected_gate`` (default
        ``gate``) is the gate used for it.
        """
        z, dist, i = self._nearest(z, kind)
        if expected is not None:
            if not 0 <= expected < len(self.contacts):
                raise ConfigError(f"{self.key}.expected", f"no contact {expected!r}")
            c = self.contacts[expected]
            d = float(c.belief.mahalanobis(z, c.belief.cov + c.belief.R))
            g = self.gate if expected_gate is None else expected_gate
            if c.kind == kind and d <= g:
                dist, i = min(d, self.gate), expected
        if (v_used is None) != (f_measured is None):
            raise ConfigError(f"{self.key}.f_measured", "give both v_used and f_measured, or none")
        if v_used is not None and kind != "collision":
            raise ConfigError(f"{self.key}.v_used", "only a collision has an approach velocity")
        if v_used is not None and f_measured is not None:
            v_used = check_positive(f"{self.key}.v_used", v_used)
            f_measured = check_finite(f"{self.key}.f_measured", f_measured)
        if i is not None and dist <= self.gate:
            fresh = not (self.once_per_trial and self.contacts[i].updated_this_trial)
            if fresh:
                self.contacts[i].belief.update(z)
            event = ContactEvent(i, False, fresh, dist)
        else:
            name = f"new{len(self.contacts) + 1}"
            i = self._append(z, self.new_contact_std, kind, name, "observed")
            event = ContactEvent(i, True, True, None)
        contact = self.contacts[i]
        contact.updated_this_trial = True
        if event.updated and contact.approach and v_used is not None and f_measured is not None:
            contact.approach.update(v_used, f_measured)
        return event

    def end_trial(self) -> None:
        """End-of-trial hook: the predict step P <- P + Q of every contact (§3.3)."""
        for c in self.contacts:
            c.belief.predict()
            c.updated_this_trial = False
        self.trial += 1

    def state_dict(self) -> dict[str, Any]:
        """JSON-safe state: format tag and version, settings, trial count and every contact."""
        names = ("dim", "gate", "once_per_trial", "key")
        stds = ("process_noise_std", "measurement_noise_std", "new_contact_std")
        settings = {n: getattr(self, n) for n in names}
        settings |= {n: getattr(self, n).tolist() for n in stds}
        fields = ("name", "kind", "source", "updated_this_trial")
        contacts = [
            {n: getattr(c, n) for n in fields}
            | {"mean": c.belief.mean.tolist(), "cov": c.belief.cov.tolist()}
            | {"n_updates": c.belief.n_updates, "approach": c.approach and c.approach.state_dict()}
            | {"lead": None if c.lead is None else c.lead.tolist()}
            for c in self.contacts
        ]
        settings["approach"] = dict(self.approach_params)
        head = {"format": _FORMAT, "format_version": _FORMAT_VERSION, "settings": settings}
        return head | {"trial": self.trial, "contacts": contacts}

    @classmethod
    def from_state_dict(cls, data: Any, key: str = "init_from") -> ContactMap:
        """Rebuild from :meth:`state_dict` output; any problem is a ConfigError named ``key``."""
        fmt = data.get("format") if isinstance(data, Mapping) else type(data).__name__
        if fmt != _FORMAT:
            raise ConfigError(key, f"not a contact map (format {fmt!r}, expected {_FORMAT!r})")
        if (version := data.get("format_version")) != _FORMAT_VERSION:
            raise ConfigError(key, f"unsupported format_version {version!r}, not {_FORMAT_VERSION}")
        try:
            out = cls(**data["settings"])
            out.trial = int(data["trial"])
            q, r = out._noise_covs()
            for i, rec in enumerate(data["contacts"]):
                k = f"{out.key}.contacts[{i}]"
                kind = check_choice(f"{k}.kind", rec["kind"], KINDS)
                belief = ContactBelief(rec["mean"], rec["cov"], q, r, key=k)
                if belief.dim != out.dim:
                    raise ConfigError(f"{k}.mean", f"must have length {out.dim}")
                belief.n_updates = int(rec["n_updates"])
                approach = rec["approach"]
                if (approach is None) != (kind == "impactless"):
                    raise ConfigError(f"{k}.approach", "a collision, and only a collision, has one")
                if approach is not None:
                    akey = f"{out.key}.approach"
                    approach = ApproachVelocityModel.from_state_dict(approach, akey)
                source = check_choice(f"{k}.source", rec["source"], SOURCES)
                flag = bool(rec["updated_this_trial"])
                lead = rec.get("lead")  # absent in maps saved before issue #38
                lead = None if lead is None else check_vector(f"{k}.lead", lead, out.dim)
                out.contacts.append(
                    Contact(belief, kind, str(rec["name"]), approach, source, flag, lead)
                )
        except ConfigError as e:
            raise ConfigError(key, f"invalid contact map: {e}") from None
        except (KeyError, TypeError, ValueError, AttributeError) as e:
            raise ConfigError(key, f"malformed contact map: {e!r}") from None
        return out

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write :meth:`state_dict` as JSON atomically (a temporary file, then ``os.replace``)."""
        path = Path(path)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(json.dumps(self.state_dict(), indent=1, allow_nan=False), encoding="utf-8")
        os.replace(tmp, path)
        return path

    @classmethod
    def load(cls, path: str | os.PathLike[str], key: str = "init_from") -> ContactMap:
        """Read a :meth:`save` file; ConfigError ``key`` if missing, corrupted or foreign."""
        try:
            data = json.loads(Path(path).read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
            raise ConfigError(key, f"cannot read contact map {str(path)!r}: {e}") from None
        try:
            return cls.from_state_dict(data, key=key)
        except ConfigError as e:
            raise ConfigError(key, f"{str(path)!r}: {e.problem}") from None
