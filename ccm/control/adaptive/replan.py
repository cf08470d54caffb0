"""The anticipating controller's plan around expected contacts (seed A §3.5, Eq. 10-11).

At the start of a trial :func:`plan_passes` finds where the planned path P passes through the
region C of each expected contact (:mod:`ccm.control.adaptive.contact_regions`). A collision
pass gets speed-limit pieces: per plan segment, ρ = v_a / the segment's top speed in C, where
v_a is the contact's learned approach velocity (Eq. 9). Holds and slow segments keep ρ = 1.
An impact-less crossing gets only its times.

Whenever the plan changes (at t = 0, and after each contact is made), :func:`rate_changes`
turns the pieces still ahead into Eq. 11 rate changes of the :class:`TimeWarp`, so the target
never moves faster than v_a inside C. Where pieces overlap, the smallest rate applies. A
slow-down is complete where its piece begins (Eq. 10: the switch is complete on reaching C);
a speed-up starts where the piece ends; each change lasts ``blend_s`` (shorter if the plan
leaves no room) with Eq. 11's C∞ profile. :func:`windows_ahead` gives each pass its
transition window (Eq. 10's weight rises over ``blend_s`` to 1 at p_c).
"""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence
from typing import Any

import numpy as np

from ccm.control.adaptive.contact_events import TransitionWindow
from ccm.control.adaptive.contact_regions import (
    approach_passes,
    in_plan_order,
    speed_pieces,
    to_segment_end,
)
from ccm.tasks.retiming import TimeWarp

#: a collision pass: (contact, φ where C begins, φ where it ends, speed-limit pieces)
Slow = tuple[int, float, float, list[tuple[float, float, float]]]
#: an impact-less crossing: (contact, φ where C begins, φ where it ends)
Crossing = tuple[int, float, float]
#: a rate change of the warp: (t_start, t_end, rate_after), wall time [s]
Change = tuple[float, float, float]


def plan_passes(
    contacts: Sequence[Any], pattern: Any, path_dt: float, sigma_scale: float, min_region: float
) -> tuple[list[Slow], list[Crossing]]:
    """The collision passes and impact-less crossings of ``pattern`` through the regions C
    of the map's ``contacts``, each list sorted by where C begins.

    Seed A §3.5.1 puts p_c where "the robot crosses" C. The target leads the tool: by its lag,
    and by the plan's designed offsets into the surfaces it presses on (1 cm into a wall it
    slides along). A contact whose ``lead`` (target − tool at its last measurement) is known
    is therefore tested on P − lead, where the tool is expected when the target is on P;
    before any measurement on P itself (issue #38 item 3: once C shrinks to millimetres, P
    passes beside it)."""
    ts = np.arange(0.0, pattern.duration + 0.5 * path_dt, path_dt)
    path = pattern.sample_many(ts)
    pos, speed = path["position"], np.linalg.norm(path["velocity"], axis=1)
    passes = [
        approach_passes(c.belief, pos if c.lead is None else pos - c.lead, sigma_scale, min_region)
        for c in contacts
    ]
    ordered = [i for i, c in enumerate(contacts) if c.kind == "collision" and c.source == "config"]
    for i, ps in zip(ordered, in_plan_order([passes[i] for i in ordered]), strict=True):
        passes[i] = ps
    slow: list[Slow] = []
    crossings: list[Crossing] = []
    for i, c in enumerate(contacts):
        for p in passes[i]:
            if c.kind != "collision":
                crossings.append((i, float(ts[p.start]), float(ts[p.exit])))
                continue
            v_a = c.approach.next_velocity() if c.approach is not None else math.inf
            p = to_segment_end(p, path["segment"])
            pieces = speed_pieces(ts, speed, path["segment"], [p], v_a)
            slow.append((i, float(ts[p.start]), float(ts[p.exit]), pieces))
    slow.sort(key=lambda e: e[1])
    crossings.sort(key=lambda e: e[1])
    return slow, crossings


def rate_changes(
    changes: list[Change],
    warp: TimeWarp,
    rate0: float,
    slow: Sequence[Slow],
    hits: Collection[int],
    t_from: float,
    phi_from: float,
    blend_s: float,
) -> tuple[TimeWarp, float]:
    """Append to ``changes`` the rate changes that the pieces still ahead of ``phi_from``
    need (contacts in ``hits`` are made: no more limits); the warp with them and its initial
    rate (changed only when the plan starts inside C)."""
    cur = changes[-1][2] if changes else rate0
    t_free = max(t_from, changes[-1][1] if changes else 0.0)
    spans = []  # (φ_start, φ_end, ρ, contact) of the speed-limit pieces still ahead
    for i, _, phi_x, pieces in slow:
        if i in hits or phi_x <= phi_from:
            continue
        spans += [(max(e, phi_from), x, r, i) for e, x, r in pieces if x > phi_from]

    def wanted(phi: float) -> float:
        return min([r for e, x, r, _ in spans if e <= phi < x] + [1.0])

    for bp in sorted({phi_from} | {e for e, *_ in spans} | {x for _, x, *_ in spans}):
        r = wanted(bp)
        if abs(r - cur) < 1e-12:
            continue
        if bp <= phi_from and t_from == 0.0 and not changes:  # starts inside C
            rate0 = cur = r
            warp = TimeWarp([], rate0=r)
            continue
        if r < cur:  # slow down, complete at bp
            phi_s = max(bp - 0.5 * (cur + r) * blend_s, float(warp.phi(t_free)))
            t_s = warp.inverse(phi_s)
            dur = max(2.0 * (bp - phi_s) / (cur + r), 0.02)
        else:  # speed up from bp
            t_s = max(warp.inverse(bp), t_free)
            dur = blend_s
        changes.append((t_s, t_s + dur, r))
        warp = TimeWarp(changes, rate0=rate0)
        cur, t_free = r, t_s + dur
    return warp, rate0


def windows_ahead(
    slow: Sequence[Slow],
    crossings: Sequence[Crossing],
    hits: Collection[int],
    warp: TimeWarp,
    t_from: float,
    phi_from: float,
    blend_s: float,
) -> list[TransitionWindow]:
    """One transition window per collision pass and impact-less crossing still ahead."""
    windows = []
    for i, phi_c, phi_x, _ in slow:
        if i in hits or phi_x <= phi_from:
            continue
        if phi_c <= phi_from:  # inside C now: the transition controller at once
            t0 = t1 = t_from
        else:
            t1 = warp.inverse(phi_c)
            t0 = max(t1 - blend_s, t_from)
        windows.append(TransitionWindow(i, "collision", t0, t1 + 1e-9, warp.inverse(phi_x)))
    for i, phi_c, phi_x in crossings:
        if phi_c > phi_from:
            t_c = warp.inverse(phi_c)
            t0 = max(t_c - blend_s, t_from)
            windows.append(TransitionWindow(i, "impactless", t0, t_c, warp.inverse(phi_x)))
    return windows
