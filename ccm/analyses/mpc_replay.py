"""Replay recorded MPC ticks through several GP-MPC problems, interleaved (seed B Table 2).

Seed B times Table 2's features "by playing back the data recorded from the rail assembly
problem". :func:`replay` does the playing back for :mod:`ccm.analyses.mpc_table2`: at every
recorded tick it solves every variant's problem (:class:`ccm.control.mpc.problem.GPMPCProblem`,
Eq. 13) once from the recorded state ξ_t = [x, ẋ], in an order rotated by one per tick
(:func:`rotation`), so a drift of the machine's load hits every variant alike. Each variant
holds what its own controller would (:class:`ccm.control.mpc.gp_mpc.GPMPC`): its warm start
(inside its problem), its last accepted f^r, M, D (an unsuccessful solve is not applied) and
its belief per tick (Eq. 12). Each solve is timed with ``time.process_time`` (the process's
CPU time, which other jobs on a shared machine do not slow) and ``time.perf_counter`` (wall).

:func:`block_bootstrap` gives the spread of a statistic of the per-tick solve times (a rate, a
ratio of two rows' rates): a paired block bootstrap over the ticks, which keeps the tick-to-tick
correlation within a block and the pairing of the rows' solves at the same tick.
"""

from __future__ import annotations

import gc
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

AXES = "xyz"


@dataclass
class Variant:
    """One Table 2 row during the replay: its problem and what its controller holds.

    Attributes:
        name: the row's name.
        problem: its :class:`GPMPCProblem` (keeps its own warm start).
        beliefs: (n_ticks, n_modes) belief b_t at each tick (Eq. 12), rows summing to 1.
        mass, damping, f_ref: the last accepted M [kg], D [N s/m], f^r [N] (n,).
        gp_points: the GP training points over all modes.
        cpu_s, wall_s, iterations, success, applied: per tick, the solve's CPU and wall time
            [s], IPOPT iterations and success, and [M, D, f^r] after it.
    """

    name: str
    problem: Any
    beliefs: np.ndarray
    mass: np.ndarray
    damping: np.ndarray
    f_ref: np.ndarray
    gp_points: int | None = None  # GP training points over all modes (for the summary)
    cpu_s: list[float] = field(default_factory=list)
    wall_s: list[float] = field(default_factory=list)
    iterations: list[int] = field(default_factory=list)
    success: list[bool] = field(default_factory=list)
    applied: list[np.ndarray] = field(default_factory=list)  # [M, D, f^r] after each tick


def rotation(n_rows: int, tick: int) -> list[int]:
    """The order in which the rows are solved at ``tick``: 0..n−1 rotated left by ``tick``
    (each row is first once every n ticks, and the same distance behind every other row)."""
    if n_rows <= 0:
        return []
    s = tick % n_rows
    return [*range(s, n_rows), *range(s)]


def replay(variants: Sequence[Variant], states: np.ndarray) -> None:
    """Solve every variant once per recorded state, interleaved (module docstring).

    Args:
        variants: the rows, each with a belief row per tick; their logs are filled in.
        states: (n_ticks, 2n) the recorded ξ_t = [x, ẋ] at each MPC tick.

    The cyclic garbage collector is paused during the replay, as during a trial
    (:func:`ccm.experiment.trial.run_trial`), so a collection does not land in one solve.
    """
    states = np.asarray(states, dtype=float)
    for v in variants:
        if len(v.beliefs) != len(states):
            raise ValueError(f"{v.name}: {len(v.beliefs)} beliefs for {len(states)} ticks")
        v.problem.reset_warm_start()
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        for k, xi in enumerate(states):
            for i in rotation(len(variants), k):
                _solve(variants[i], xi, k)
    finally:
        if was_enabled:
            gc.enable()


def _solve(v: Variant, xi: np.ndarray, k: int) -> None:
    """One timed solve of ``v`` at tick ``k``; applied as its controller would."""
    t0, c0 = time.perf_counter(), time.process_time()
    sol = v.problem.solve(xi, v.beliefs[k], v.mass, v.damping, v.f_ref)
    c1, t1 = time.process_time(), time.perf_counter()
    v.cpu_s.append(c1 - c0)
    v.wall_s.append(t1 - t0)
    v.iterations.append(int(sol.iterations))
    v.success.append(bool(sol.success))
    if sol.success:  # as GPMPC: a failed solve keeps the last feasible f^r, M, D
        v.mass, v.damping, v.f_ref = sol.mass, sol.damping, sol.f_ref
    v.applied.append(np.concatenate([v.mass, v.damping, v.f_ref]))


def row_summary(v: Variant, dim: int) -> dict[str, Any]:
    """The deterministic facts of one replayed row (summary.json): ``ticks``, ``n_modes``,
    ``gp_points``, the median and largest IPOPT iterations, ``infeasible`` (unsuccessful
    solves, not applied), the range of the applied M and D per axis and, with several modes,
    the largest final belief."""
    it = np.asarray(v.iterations, dtype=float)
    applied = np.asarray(v.applied)
    out: dict[str, Any] = {
        "ticks": len(it),
        "n_modes": int(v.beliefs.shape[1]),
        "gp_points": v.gp_points,
        "iterations_median": float(np.median(it)),
        "iterations_max": float(np.max(it)),
        "infeasible": int(len(it) - sum(v.success)),
    }
    for j, a in enumerate(AXES[:dim]):
        for name, col, unit in (("mass", j, "kg"), ("damping", dim + j, "Nspm")):
            out[f"{name}_{a}_min_{unit}"] = float(applied[:, col].min())
            out[f"{name}_{a}_max_{unit}"] = float(applied[:, col].max())
    if v.beliefs.shape[1] > 1:
        out["belief_max_final"] = float(v.beliefs[-1].max())
    return out


def rates(v: Variant) -> dict[str, float | None]:
    """Seed B Table 2's "MPC rate" of a replayed row: 1 / median solve time, from CPU and
    wall time [Hz], the median IPOPT iterations and the CPU milliseconds per iteration."""
    cpu, wall = np.asarray(v.cpu_s), np.asarray(v.wall_s)
    it = np.asarray(v.iterations, dtype=float)
    pos = it > 0
    return {
        "mpc_cpu_rate_hz": _inverse(np.median(cpu)) if len(cpu) else None,
        "mpc_rate_hz": _inverse(np.median(wall)) if len(wall) else None,
        "mpc_iterations_median": float(np.median(it)) if len(it) else None,
        "mpc_ms_per_iteration": float(1e3 * np.median(cpu[pos] / it[pos])) if pos.any() else None,
    }


def _inverse(x: float) -> float | None:
    return 1.0 / float(x) if x > 0 else None


def block_bootstrap(
    series: Sequence[np.ndarray],
    stat: Callable[..., float],
    rng: np.random.Generator,
    resamples: int,
    block: int,
    level: float = 0.95,
) -> tuple[float, float, float]:
    """``stat(*series)`` and its percentile interval from a paired block bootstrap.

    The ticks 0..n−1 are cut into consecutive blocks of ``block`` ticks (the last one
    shorter); a resample draws ⌈n / block⌉ blocks with replacement and keeps the first n of
    their ticks, the same ticks for every series (paired).

    Args:
        series: equal-length per-tick arrays (e.g. two rows' CPU times).
        stat: statistic of the (resampled) series, e.g. a ratio of medians.
        rng: the seeded generator.
        resamples: number of bootstrap resamples (≥ 1).
        block: ticks per block (≥ 1).
        level: two-sided coverage of the interval, in (0, 1).

    Returns:
        (the statistic on the data, the lower and the upper percentile of the resamples).
    """
    arrs = [np.asarray(s, dtype=float) for s in series]
    n = len(arrs[0])
    if n == 0 or any(len(a) != n for a in arrs):
        raise ValueError("block_bootstrap needs non-empty series of equal length")
    if resamples < 1 or block < 1 or not 0.0 < level < 1.0:
        raise ValueError("block_bootstrap: resamples, block >= 1 and level in (0, 1)")
    starts = np.arange(0, n, block)
    n_draw = math.ceil(n / block)
    values = np.empty(resamples)
    for r in range(resamples):
        idx = np.concatenate([np.arange(s, min(s + block, n)) for s in rng.choice(starts, n_draw)])
        idx = idx[:n]
        values[r] = stat(*(a[idx] for a in arrs))
    tail = 100.0 * (1.0 - level) / 2.0
    lo, hi = np.percentile(values, [tail, 100.0 - tail])
    return float(stat(*arrs)), float(lo), float(hi)


def rate_of(cpu: np.ndarray) -> float:
    """1 / median solve time [Hz]."""
    return 1.0 / float(np.median(cpu))


def rate_ratio(cpu_a: np.ndarray, cpu_b: np.ndarray) -> float:
    """Row a's rate over row b's: median(b) / median(a) of their solve times."""
    return float(np.median(cpu_b)) / float(np.median(cpu_a))


def timing_info(
    variants: Sequence[Variant],
    pairs: Sequence[tuple[str, str]],
    reference_hz: Mapping[str, float],
    boot: Mapping[str, Any],
    seed: int,
) -> dict[str, Any]:
    """run_info.json's timing of a replay.

    Args:
        variants: the replayed rows.
        pairs: (a, b) row pairs whose rate ratio a / b is reported.
        reference_hz: the paper's rate per row [Hz] (seed B Table 2), reported beside.
        boot: {resamples, block_ticks, level} of :func:`block_bootstrap`.
        seed: seeds the bootstrap's generator.

    Returns:
        Per row the rates of :func:`rates` under their keys (``mpc_cpu_rate_hz``: {row: Hz},
        ..., the shape ``ccm report`` joins to the conditions) and ``table2``: each row's CPU
        and wall rate and each pair's ratio as [value, low, high] of the bootstrap interval.
    """
    per = {v.name: rates(v) for v in variants}
    keys = ("mpc_cpu_rate_hz", "mpc_rate_hz", "mpc_iterations_median", "mpc_ms_per_iteration")
    info: dict[str, Any] = {
        k: {name: r[k] for name, r in per.items() if r[k] is not None} for k in keys
    }
    rng = np.random.default_rng(seed)  # the spread only (run_info.json)

    def interval(series: Sequence[Sequence[float]], stat: Callable[..., float]) -> list[float]:
        arrs = [np.asarray(s, dtype=float) for s in series]
        res = block_bootstrap(
            arrs, stat, rng, boot["resamples"], boot["block_ticks"], boot["level"]
        )
        return list(res)

    by = {v.name: v for v in variants}
    rows = {
        v.name: {
            "cpu_rate_hz": interval([v.cpu_s], rate_of),
            "wall_rate_hz": interval([v.wall_s], rate_of),
            "seed_b_hz": reference_hz.get(v.name),
        }
        for v in variants
    }
    ratios = {
        f"{a}/{b}": {
            "cpu": interval([by[a].cpu_s, by[b].cpu_s], rate_ratio),
            "wall": interval([by[a].wall_s, by[b].wall_s], rate_ratio),
            "seed_b": reference_hz[a] / reference_hz[b]
            if a in reference_hz and b in reference_hz
            else None,
        }
        for a, b in pairs
    }
    info["table2"] = {
        "rows": rows,
        "ratios": ratios,
        "bootstrap": {**boot, "seed": seed, "over": "ticks, paired, in blocks"},
    }
    return info
