"""Where the plan meets a contact region C, and how fast it may move there (seed A §3.3, §3.5).

Region C of a contact is the ellipsoid {x : (x − c)ᵀ S⁻¹ (x − c) <= s²} of the *innovation*
covariance S = P + R: where the next detected contact is expected, the belief's own uncertainty
P plus the detection noise R (the map's ``measurement_noise_std``). Along a straight approach
through c its extent is s·σ_â, σ_â² = âᵀ S â, before and after c. An optional floor
``min_radius`` on its semi-axes (R counts toward it: :func:`region_mask`) is off in the H4
experiments (issue #17 item 2). It once stood in for the tool's lag behind its target: with C at
3σ of P + R alone (≈ 1.6 cm once converged) the tool, whose lag grows from ~5 mm to ~1.1 cm as
the stiffness falls to K*, stalled by friction after the slow-down, and the old stall test took
that for the contact 2 cm short of h4_contact_learning's obstacle (60 N when the plan's speed
came back; seed 0, trial 2). The stall test now asks for a lag beyond the sliding resistance
(:meth:`ccm.control.adaptive.contact_events.ContactEvents._pressed`). The target's offset
from the tool across the motion (its designed press into the surfaces) is a contact's
``lead``, by which the caller shifts the path (:func:`ccm.control.adaptive.replan.plan_passes`).

A *pass* is a maximal run of plan samples inside C, from where the path enters C to where it
leaves it. A path may enter C several times (a wide early belief covers earlier stretches of
the plan too). A collision's passes are capped while the path moves toward that contact, which
the robot can only tell by the plan's order (:func:`in_plan_order`): a pass counts from where
the first pass of the contact before it in the plan begins. The direction to the belief mean is
no test of "toward": the mean can lie behind the path (seed 5 of h4_collisions: the table
belief, 0.06 m off, is 4 mm above the start of the descent onto the table, so every sample of
the descent moves away from it), and the contact can lie anywhere in C ahead.

Eq. 11's speed limit (:func:`speed_pieces`): each capped pass is cut at the plan's segment
boundaries, and the stretch of each piece where the plan is faster than v_a gets the rate ρ =
v_a / the plan's top speed there, so the target moves no faster than v_a anywhere in C, while
holds and the parts of segments already at most v_a keep the plan's own timing. (A constant ρ
per stretch keeps the Eq. 11 blends between constant rates; a cap exactly at v_a at every point
would need a rate that varies with the plan's speed.) Where the pieces of several contacts
overlap, the smallest rate applies (the caller's ``wanted``); nothing outside C is slowed.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ccm.learn.contact.belief import ContactBelief

__all__ = [
    "Pass",
    "approach_passes",
    "in_plan_order",
    "region_mask",
    "speed_pieces",
    "to_segment_end",
]


@dataclass(frozen=True)
class Pass:
    """One pass through a contact's region C, as plan-sample indices: ``start`` is the first
    sample in C and ``exit`` the first sample out of it again (or the plan's last sample)."""

    start: int
    exit: int


def region_mask(
    belief: ContactBelief, points: np.ndarray, sigma_scale: float, min_radius: float = 0.0
) -> np.ndarray:
    """Whether each point (N, d) lies in C, the ``sigma_scale`` ellipsoid of S = P + R, with
    its semi-axes floored at ``min_radius`` [m]: R counts toward the floor, so S gets only the
    variance the floor asks for beyond R's largest, max(0, (r/s)² − max R_ii) I."""
    extra = max(0.0, (min_radius / sigma_scale) ** 2 - float(np.max(np.diag(belief.R))))
    cov = belief.cov + belief.R + extra * np.eye(belief.dim)
    dist = belief.mahalanobis(points, cov=cov, name="path")
    return np.atleast_1d(np.asarray(dist) <= sigma_scale)


def approach_passes(
    belief: ContactBelief, pos: np.ndarray, sigma_scale: float, min_radius: float = 0.0
) -> list[Pass]:
    """The passes of a sampled plan (positions (N, d)) through C, in plan order."""
    inside = region_mask(belief, pos, sigma_scale, min_radius)
    padded = np.concatenate([[False], inside, [False]])
    edges = np.flatnonzero(np.diff(padded.astype(np.int8)))
    last = len(pos) - 1
    return [
        Pass(int(k0), min(int(k1), last)) for k0, k1 in zip(edges[::2], edges[1::2], strict=True)
    ]


def in_plan_order(passes: Sequence[Sequence[Pass]]) -> list[list[Pass]]:
    """Trim the passes of each contact to begin no earlier than the first remaining pass of
    the contact before it (``passes`` lists the contacts in the order the plan meets them);
    a pass that ends before that is dropped. A contact without passes does not constrain the
    next one.
    """
    out, earliest = [], 0
    for ps in passes:
        kept = [Pass(max(p.start, earliest), p.exit) for p in ps if p.exit > earliest]
        if kept:
            earliest = kept[0].start
        out.append(kept)
    return out


def to_segment_end(p: Pass, segment: np.ndarray) -> Pass:
    """``p`` with its exit moved to the end of the plan segment in which the path left C.

    The tool trails its target: with K* = 300 N/m and 3.5 N of friction along a wall, by
    ~1.2 cm, more than the half-width of a converged region (3σ of P + R: ≈ 1.6 cm with a
    5 mm R, ≈ 3 mm with the measured 0.11 mm R of issue #38). The target
    then leaves C before the tool reaches the contact, and the plan's speed came back for the
    impact (h4_contact_learning's obstacle, 16-101 N in trials 3-5 of seed 0, measured). The
    plans end their approach segments inside the surface they meet, so the cap holds until
    that segment ends (or the contact is made), not only until the target leaves C.
    """
    last = p.exit - 1 if p.exit > p.start else p.exit
    later = np.flatnonzero(segment[last:] != segment[last])
    end = last + int(later[0]) if later.size else len(segment) - 1
    return Pass(p.start, max(p.exit, end))


def speed_pieces(
    ts: np.ndarray,
    speed: np.ndarray,
    segment: np.ndarray,
    passes: Sequence[Pass],
    v_a: float,
) -> list[tuple[float, float, float]]:
    """Eq. 11 speed-limit pieces ``(φ_start, φ_end, ρ)`` of ``passes``, in plan time.

    Each pass is cut where the plan's ``segment`` index changes; within a segment only the
    stretch where the plan is faster than v_a is slowed (from the sample before the plan's
    speed first exceeds v_a to the sample after it last does), at ρ = v_a / its top speed.
    Holds and stretches at most v_a keep ρ = 1 and are left out.
    """
    out = []
    for p in passes:
        bounds = [p.start]
        seg = segment[p.start : p.exit + 1]
        bounds += [p.start + int(k) for k in np.flatnonzero(np.diff(seg)) + 1]
        bounds.append(p.exit)
        for k0, k1 in zip(bounds[:-1], bounds[1:], strict=True):
            fast = np.flatnonzero(speed[k0 : k1 + 1] > v_a)
            if fast.size == 0:
                continue  # a hold, or a segment already at most v_a here: the plan's timing
            a, b = k0 + max(int(fast[0]) - 1, 0), min(k0 + int(fast[-1]) + 1, k1)
            out.append((float(ts[a]), float(ts[b]), v_a / float(np.max(speed[a : b + 1]))))
    return out
