"""GP contact models from simulated demonstrations (seed B §5.3, Fig. 5; §3.1, Eq. 1-3).

Seed B fits GP force models with the hinge mean (Eq. 3) to contact data and compares
(a) human-guided against autonomous contact, (b) a fixed against a varying contact position
and (c) environments of 15, 45 and 126 N/mm. This analysis makes that data in the planar
pymunk world (:class:`ccm.sim.pymunk.backend.Pymunk2D`) with a compliant wall ahead of the robot
along +x (normal -x) and, for human guidance, a simulated hand (:mod:`ccm.sim.pymunk.hri`).

The robot renders the fixed admittance M ẍ + D ẋ = f − f^r (seed B Eq. 4, K dropped) with
the inner loop of :class:`ccm.control.mpc.gp_mpc.GPMPC` (``mpc=False``: backward-Euler reference
at the control rate, tracked by a stiff PD with mass feed-forward):

* **autonomous**: no human, a constant f^r < 0 drives the robot into the wall;
* **human**: f^r = 0; the hand pulls toward a goal beyond the wall; the one F/T sensor
  measures the sum of hand and wall force (seed B §3.1).

Each demonstration records (x, f_x) of the EE centre at ``record_hz``. One GP per case,
1-D input x (the only pose coordinate the wall depends on; y stays near 0) to output f_x,
hinge mean ``c1 + c2 max(0, x − c3)`` (:class:`ccm.learn.gp.gp_force.GPForceModel`), fitted by
NLL on at most ``gp.max_points`` samples evenly thinned in time (the rule of
:class:`GPMPC`). The identified contact position is c3 and the identified stiffness −c2 (the
wall pushes along −x as the penetration grows). The truth comes from the simulator's truth
record: the wall surface ``wall_x_m − wall_offset_m`` of each demonstration (their mean for a
varying wall) and the configured stiffness. The wall acts on the EE centre, so the hinge and
the truth refer to the same point.

Predictive std: ``pred_std_*`` is the std of a new *measurement*, sqrt(latent var + σ_n²);
``latent_std_*`` leaves out the noise. Both are averaged over a grid of x: within
``contact_window_m`` of the true contact (clipped to the range of the data) and over
``free_window_m`` (distances before the true contact, in free space); ``None`` when a window
holds no data. ``mpc_std_*`` is sqrt(Σ^f) of the model the MPC uses, fitted to the same points
with ``gp.mpc_variance`` (gp_mpc's ``gp.variance``: ``tied``, seed B's Eq. 1-2 as printed,
where one σ_n² is the kernel amplitude and the noise): the variance that enters the MPC's
covariance cost and the chance constraint (issue #37), over the same windows.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig

from ccm.core.errors import (
    ConfigError,
    check_bounds,
    check_choice,
    check_finite,
    check_int_nonneg,
    check_int_positive,
    check_keys,
    check_nonneg,
    check_positive,
    config_block,
    to_plain,
)
from ccm.core.records import write_atomic, write_json_atomic
from ccm.core.timeseries import (
    FLOAT32_BITS,
    check_bits,
    check_mode,
    keep_trial,
    trial_path,
    write_timeseries,
)
from ccm.plots.gp_contact import write_gp_contact_figure

GUIDANCE = ("autonomous", "human")
POSITIONS = ("fixed", "varying")
_KEYS = (
    "demos", "duration_s", "record_hz", "wall_x_m", "start_distance_m", "stiffnesses_Npm",
    "reference_stiffness_Npm", "guidance", "positions", "position_jitter_m",
    "wall_damping_Nspm", "admittance", "robot", "autonomous_f_ref_N", "human", "gp",
    "contact_window_m", "free_window_m",
)  # fmt: skip
_SUB = {
    "admittance": ("mass_kg", "damping_Nspm"),
    "robot": ("mass_kg", "kp_Npm", "kd_Nspm"),
    "human": ("goal_beyond_wall_m", "stiffness_Npm", "damping_Nspm", "max_force_N",
              "noise_std_N", "noise_cutoff_hz"),
    "gp": ("max_points", "n_restarts", "hinge_form", "length_scale_bounds", "signal_var_bounds",
           "noise_var_bounds", "mpc_variance"),
}  # fmt: skip


# ----------------------------------------------------------------------------- settings
def _settings(cfg: DictConfig) -> dict[str, Any]:
    s = config_block(cfg, "gp_contact", _KEYS)
    for name, keys in _SUB.items():
        sub = s.get(name)
        if not isinstance(sub, dict):
            raise ConfigError(f"gp_contact.{name}", f"must be a mapping of {', '.join(keys)}")
        check_keys(f"gp_contact.{name}", sub, keys)
    s["demos"] = check_int_positive("gp_contact.demos", s.get("demos"))
    for k in ("duration_s", "record_hz", "start_distance_m", "contact_window_m"):
        s[k] = check_positive(f"gp_contact.{k}", s.get(k))
    for k in ("wall_x_m", "autonomous_f_ref_N"):
        s[k] = check_finite(f"gp_contact.{k}", s.get(k))
    for k in ("position_jitter_m", "wall_damping_Nspm"):
        s[k] = check_nonneg(f"gp_contact.{k}", s.get(k))
    s["free_window_m"] = check_bounds("gp_contact.free_window_m", s.get("free_window_m"))
    ks = s.get("stiffnesses_Npm")
    if not isinstance(ks, list) or not ks:
        raise ConfigError("gp_contact.stiffnesses_Npm", f"must be a non-empty list, got {ks!r}")
    s["stiffnesses_Npm"] = [check_positive(f"gp_contact.stiffnesses_Npm[{i}]", k)
                            for i, k in enumerate(ks)]  # fmt: skip
    if len({case_name("", "", k) for k in s["stiffnesses_Npm"]}) != len(ks):
        raise ConfigError("gp_contact.stiffnesses_Npm", f"must be distinct in N/mm, got {ks!r}")
    s["reference_stiffness_Npm"] = check_positive(
        "gp_contact.reference_stiffness_Npm", s.get("reference_stiffness_Npm")
    )
    for key, allowed in (("guidance", GUIDANCE), ("positions", POSITIONS)):
        vals = s.get(key)
        if not isinstance(vals, list) or not vals:
            raise ConfigError(f"gp_contact.{key}", f"must be a non-empty list of {allowed}")
        for i, v in enumerate(vals):
            check_choice(f"gp_contact.{key}[{i}]", v, allowed)
    a, r, h, g = s["admittance"], s["robot"], s["human"], s["gp"]
    for blk, d in (("admittance", a), ("robot", r)):
        for k in _SUB[blk]:
            d[k] = check_positive(f"gp_contact.{blk}.{k}", d.get(k))
    for k in ("goal_beyond_wall_m", "stiffness_Npm", "max_force_N", "noise_cutoff_hz"):
        h[k] = check_positive(f"gp_contact.human.{k}", h.get(k))
    for k in ("damping_Nspm", "noise_std_N"):
        h[k] = check_nonneg(f"gp_contact.human.{k}", h.get(k))
    g["max_points"] = check_int_positive("gp_contact.gp.max_points", g.get("max_points"))
    g["n_restarts"] = check_int_nonneg("gp_contact.gp.n_restarts", g.get("n_restarts"))
    _make_gp(g, 0)  # validates hinge_form and the bounds before anything is simulated
    choices = ("separate", "tied")
    g["mpc_variance"] = check_choice("gp_contact.gp.mpc_variance", g.get("mpc_variance"), choices)
    steps = s["record_every"] = round(1.0 / (s["record_hz"] * _control_dt(cfg)))
    if steps < 1 or abs(steps * s["record_hz"] * _control_dt(cfg) - 1.0) > 1e-9:
        raise ConfigError(
            "gp_contact.record_hz", "must divide the control rate 1/(sim.dt decimation)"
        )
    if cfg.experiment.get("fast", False):  # smoke tests: the one case autonomous_fixed_<ref>
        s["guidance"], s["positions"] = ["autonomous"], ["fixed"]
        s["stiffnesses_Npm"] = [s["reference_stiffness_Npm"]]
    return s


def _control_dt(cfg: DictConfig) -> float:
    from ccm.sim.pymunk.config import Pymunk2DConfig

    sim = Pymunk2DConfig.from_mapping(cfg.sim, "sim")
    return sim.dt * sim.control_decimation


def case_name(guidance: str, position: str, stiffness: float) -> str:
    """``<guidance>_<position>_<stiffness in N/mm>``, e.g. ``autonomous_fixed_45``."""
    return f"{guidance}_{position}_{stiffness / 1000.0:g}"


def fig5_panels(ref_k: float, stiffnesses: list[float]) -> list[tuple[str, list[tuple[str, str]]]]:
    """(title, [(case, label), ...]) for Fig. 5 (a), (b), (c)."""
    ref = f"{ref_k / 1e3:g} N/mm"
    return [
        (f"(a) human-guided vs autonomous, fixed position, {ref}",
         [(case_name("autonomous", "fixed", ref_k), "autonomous"),
          (case_name("human", "fixed", ref_k), "human-guided")]),
        (f"(b) fixed vs varying contact position, autonomous, {ref}",
         [(case_name("autonomous", "fixed", ref_k), "fixed position"),
          (case_name("autonomous", "varying", ref_k), "varying position")]),
        ("(c) environment stiffness, autonomous, fixed position",
         [(case_name("autonomous", "fixed", k), f"{k / 1e3:g} N/mm") for k in stiffnesses]),
    ]  # fmt: skip


# ----------------------------------------------------------------------------- simulation
def simulate_demo(
    s: dict[str, Any], sim_cfg: Any, guidance: str, stiffness: float, jitter: float, seed: int
) -> dict[str, Any]:
    """One demonstration: reset with ``seed``, render the admittance for ``duration_s``.

    Returns ``t``, ``x``, ``f`` (measured f_x) at ``record_hz``, the wall offset drawn at reset
    and the true contact position (truth record; for metrics only).
    """
    from ccm.control.mpc.gp_mpc import GPMPC
    from ccm.core.types import TargetSample
    from ccm.sim.pymunk.backend import Pymunk2D
    from ccm.sim.pymunk.config import Pymunk2DConfig
    from ccm.sim.pymunk.scene import SceneSpec

    wall_x, r, h = s["wall_x_m"], s["robot"], s["human"]
    scene: dict[str, Any] = {
        "ee": {"mass": r["mass_kg"]},
        "compliant_walls": [{"point": [wall_x, 0.0], "normal": [-1.0, 0.0],
                             "stiffness": stiffness, "damping": s["wall_damping_Nspm"],
                             "position_jitter_m": jitter}],
    }  # fmt: skip
    human = guidance == "human"
    if human:
        scene["human"] = {
            "goals": [[wall_x + h["goal_beyond_wall_m"], 0.0]], "stiffness": h["stiffness_Npm"],
            "damping": h["damping_Nspm"], "max_force": h["max_force_N"],
            "noise_std": h["noise_std_N"], "noise_cutoff_hz": h["noise_cutoff_hz"],
        }  # fmt: skip
    config = Pymunk2DConfig.from_mapping(sim_cfg, "sim")
    sim = Pymunk2D(SceneSpec.from_mapping(scene, "gp_contact.scene"),
                   [wall_x - s["start_distance_m"], 0.0], config)  # fmt: skip
    a = s["admittance"]
    ctl = GPMPC(  # mpc=False: the fixed admittance, its inner loop only
        mpc=False,
        init_f_ref=[0.0 if human else s["autonomous_f_ref_N"], 0.0],
        init_mass=a["mass_kg"],
        init_damping=a["damping_Nspm"],
        mass_kg=r["mass_kg"],
        inner_kp=r["kp_Npm"],
        inner_kd=r["kd_Nspm"],
        key="gp_contact.controller",
    )
    obs, info = sim.reset(seed)
    ctl.reset(2, sim.dt * sim.control_decimation)
    target = TargetSample(0.0, np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(1))
    n = round(s["duration_s"] / (sim.dt * sim.control_decimation))
    rows = []
    for i in range(n + 1):
        if i % s["record_every"] == 0:
            rows.append((obs.t, obs.position[0], obs.force[0]))
        if i < n:
            obs, info = sim.step(ctl.step(obs, target))
    sim.close()
    t, x, f = (np.array(c) for c in zip(*rows, strict=True))
    offset = float(info.extra["wall_offset_m"])
    return {"t": t, "x": x, "f": f, "wall_offset_m": offset, "contact_m": wall_x - offset}


# ----------------------------------------------------------------------------- fitting
def fit_case(
    s: dict[str, Any], demos: list[dict[str, Any]], stiffness: float, seed: int
) -> tuple[dict[str, Any], dict[str, Any]]:
    """Fit the hinge-mean GP to a case's demonstrations; metrics and curves for the figure."""
    x = np.concatenate([d["x"] for d in demos])
    f = np.concatenate([d["f"] for d in demos])
    idx = np.unique(np.linspace(0, len(x) - 1, s["gp"]["max_points"]).round().astype(int))
    gp = _make_gp(s["gp"], seed)
    mpc_gp = _make_gp(s["gp"], seed, s["gp"]["mpc_variance"])
    with _one_blas_thread():  # small matrices: threads only add overhead (and noise in timing)
        gp.fit(x[idx, None], f[idx])
        mpc_gp.fit(x[idx, None], f[idx])
    c1, c2, c3 = gp.hinge_
    true = float(np.mean([d["contact_m"] for d in demos]))
    w = s["contact_window_m"]
    lo_f, hi_f = s["free_window_m"]

    def std(lo: float, hi: float) -> tuple[float | None, float | None, float | None]:
        lo, hi = max(lo, x.min()), min(hi, x.max())  # within the data
        if lo >= hi:
            return None, None, None
        grid = np.linspace(lo, hi, 101)[:, None]
        var, mpc_var = gp.predict(grid)[1], mpc_gp.predict(grid)[1]
        pred = float(np.mean(np.sqrt(var + gp.noise_var_)))
        return pred, float(np.mean(np.sqrt(var))), float(np.mean(np.sqrt(mpc_var)))

    pc, lc, mc = std(true - w, true + w)
    pf, lf, mf = std(true - hi_f, true - lo_f)
    metrics = {
        "contact_position_true_m": true,
        "contact_position_identified_m": float(c3),
        "contact_position_error_m": float(c3) - true,
        "contact_position_spread_m": float(np.ptp([d["contact_m"] for d in demos])),
        "stiffness_true_Npm": float(stiffness),
        "stiffness_identified_Npm": -float(c2),
        "stiffness_ratio": -float(c2) / stiffness,
        "free_force_identified_N": float(c1),
        "pred_std_contact_N": pc,
        "pred_std_free_N": pf,
        "latent_std_contact_N": lc,
        "latent_std_free_N": lf,
        "mpc_std_contact_N": mc,
        "mpc_std_free_N": mf,
        "noise_std_N": float(np.sqrt(gp.noise_var_)),
        "signal_std_N": float(np.sqrt(gp.signal_var_)),
        "length_scale_m": float(gp.length_scales_[0]),
        "nll": float(gp.nll_),
        "n_points": len(idx),
    }
    grid = np.linspace(x.min(), x.max() + 5e-4, 600)  # data range (+0.5 mm): no extrapolation
    mu, var = gp.predict(grid[:, None])
    curves = {"x": x, "f": f, "grid": grid, "mu": mu, "std": np.sqrt(var + gp.noise_var_),
              "true": true, "contacts": [d["contact_m"] for d in demos]}  # fmt: skip
    return metrics, curves


def _make_gp(g: dict[str, Any], seed: int, variance: str = "separate") -> Any:
    """The hinge-mean GP of the settings (``variance``: ``gp.mpc_variance`` for the MPC's)."""
    from ccm.learn.gp.gp_force import GPForceModel

    return GPForceModel(mean="hinge", hinge_form=g.get("hinge_form"),
                        length_scale_bounds=g.get("length_scale_bounds"),
                        signal_var_bounds=g.get("signal_var_bounds"),
                        noise_var_bounds=g.get("noise_var_bounds"), n_restarts=g["n_restarts"],
                        variance=variance, seed=seed, key="gp_contact.gp")  # fmt: skip


def _one_blas_thread() -> contextlib.AbstractContextManager:
    try:  # threadpoolctl comes with scikit-learn
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


# ----------------------------------------------------------------------------- run
def run_gp_contact_models(cfg: DictConfig, compose: Callable, out_dir: Path) -> dict[str, Any]:
    """Simulate the demonstrations of every case, fit the GPs, write figure, table, summary."""
    s = _settings(cfg)
    t0 = time.perf_counter()
    seed = int(cfg.seed)
    root = np.random.default_rng(seed)
    # one reset seed per demonstration, shared by every case (common random numbers: a
    # varying wall takes the same offsets for every guidance and stiffness), then the seed of
    # the GP restarts; the draws never depend on which cases are run
    demo_seeds = root.integers(0, 2**31 - 1, size=s["demos"])
    gp_seed = int(root.integers(0, 2**31 - 1))
    sim_cfg = to_plain(cfg.sim)
    conditions: dict[str, dict[str, Any]] = {}
    trials: list[dict[str, Any]] = []
    curves: dict[str, dict[str, Any]] = {}
    mode = check_mode(cfg.experiment.get("timeseries", "first_last"))
    bits = check_bits(cfg.experiment.get("timeseries_bits", FLOAT32_BITS))
    timing: dict[str, float] = {}
    for guidance in GUIDANCE:
        if guidance not in s["guidance"]:
            continue
        for position in POSITIONS:
            if position not in s["positions"]:
                continue
            jitter = s["position_jitter_m"] if position == "varying" else 0.0
            for k in s["stiffnesses_Npm"]:
                name = case_name(guidance, position, k)
                tc = time.perf_counter()
                demos = [
                    simulate_demo(s, sim_cfg, guidance, k, jitter, int(ds)) for ds in demo_seeds
                ]
                conditions[name], curves[name] = fit_case(s, demos, k, gp_seed)
                timing[name] = time.perf_counter() - tc
                for j, d in enumerate(demos, start=1):
                    trials.append(_trial_row(name, j, d))
                    if keep_trial(mode, j - 1, len(demos)):  # experiment.timeseries
                        columns = {"t": d["t"], "pos_x": d["x"], "force_x": d["f"]}
                        write_timeseries(trial_path(out_dir, name, j), columns, bits)
    write_atomic(out_dir / "gp_contact_models.md", markdown_table(conditions))
    cpu0 = time.process_time()
    if cfg.experiment.get("figures", True):
        stiffnesses = sorted(
            {float(n.rsplit("_", 1)[1]) * 1e3 for n in curves if n.startswith("autonomous_fixed_")}
        )
        panels = fig5_panels(s["reference_stiffness_Npm"], stiffnesses)
        write_gp_contact_figure(out_dir / "figures" / "gp_contact_models.png", curves, panels)
    summary = {"experiment": str(cfg.experiment.name), "status": "ok", "seed": seed,
               "conditions": conditions, "trials": trials}  # fmt: skip
    info = {"wall_time_s": time.perf_counter() - t0, "case_s": timing,
            "cpu_s": {"figures": time.process_time() - cpu0}}  # fmt: skip
    write_json_atomic(out_dir / "run_info.json", info)
    write_json_atomic(out_dir / "summary.json", summary)
    return summary


def _trial_row(name: str, demo: int, d: dict[str, Any]) -> dict[str, Any]:
    pen = d["x"] - d["contact_m"]
    tail = d["t"] >= d["t"][-1] - 0.2  # last 0.2 s: the steady press
    return {
        "condition": name,
        "trial": demo,
        "wall_offset_m": d["wall_offset_m"],
        "contact_position_true_m": d["contact_m"],
        "max_penetration_m": float(pen.max()),
        "steady_force_N": float(np.mean(d["f"][tail])),
        "in_contact_fraction": float(np.mean(pen > 0.0)),
    }


def markdown_table(conditions: dict[str, dict[str, Any]]) -> str:
    """The per-case metrics as a Markdown table (written to ``gp_contact_models.md``)."""
    lines = [
        "# gp_contact_models (seed B §5.3, Fig. 5)", "",
        "| case | contact error [mm] | stiffness identified [N/mm] | true [N/mm] | ratio "
        "| pred. std contact [N] | pred. std free [N] | noise std [N] | NLL |",
        "|---|---|---|---|---|---|---|---|---|",
    ]  # fmt: skip
    for name, m in conditions.items():
        lines.append(
            f"| {name} | {1e3 * m['contact_position_error_m']:+.2f} "
            f"| {m['stiffness_identified_Npm'] / 1e3:.1f} | {m['stiffness_true_Npm'] / 1e3:.0f} "
            f"| {m['stiffness_ratio']:.2f} | {_fmt(m['pred_std_contact_N'])} "
            f"| {_fmt(m['pred_std_free_N'])} | {m['noise_std_N']:.2f} | {m['nll']:.1f} |"
        )
    return "\n".join(lines) + "\n"


def _fmt(v: float | None) -> str:
    return "n/a" if v is None else f"{v:.2f}"
