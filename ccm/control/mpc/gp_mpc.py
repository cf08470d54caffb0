"""GP model-predictive impedance control of Haninger et al. (seed B), as a ccm controller.

Life cycle over the trials of a condition (seed B §3.1.1, §6):

1. **Demonstrations** (the first ``len(demo_modes)`` trials, ≤ 3 per mode in seed B): the
   robot renders a fixed admittance (``demo_mass``, ``demo_damping``, force reference
   ``demo_f_ref``) while the simulated human (or the constant ``demo_f_ref`` alone: an
   autonomous demonstration, seed B §5.3) moves it. Pose and *measured* force are recorded;
   ``demo_modes[i]`` is the mode (human goal) the teacher demonstrated in demo i.
   With ``mpc.disturbance.alpha: demonstrations`` the measured force of every demonstration
   is also kept at the control rate, for α of Eq. 16 (:mod:`ccm.control.mpc.disturbance_estimate`).
2. After the last demonstration, one set of GP force models per mode is fitted by NLL
   (:class:`ccm.learn.gp.gp_force.GPForceModels`, Eq. 1-3) and the MPC problem of Eq. 13 is
   built once (:class:`ccm.control.mpc.problem.GPMPCProblem`).
3. **Execution** (later trials): every ``mpc_period_s`` the MPC solves for f^r, M and D
   from the measured state, and the mode belief is updated from the measured force
   (Eq. 12, :func:`ccm.control.mpc.terms.belief_update`). A solve that IPOPT does not report
   as successful is not applied: the last feasible f^r, M, D stay and the event is counted.

Inner loop (1 kHz, the control step): the admittance f − f^r = M ẍ + D ẋ (Eq. 4, K dropped)
is integrated with backward Euler from the measured force f, giving a reference x_r, v_r that
the robot's stiff position controller tracks (seed B renders the admittance on a
position-controlled robot, §3.2): command = m a_r + K_p (x_r − x) + K_d (v_r − v). The
controller sees only the Observation.

``mpc=false`` gives the fixed-impedance admittance baseline (e.g. seed B Table 3's "high
impedance"): no demonstrations or models, the initial impedance throughout.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ccm.control.base import Controller
from ccm.control.mpc.settings import vector
from ccm.core.errors import ConfigError, check_nonneg, check_positive
from ccm.core.types import Command, Observation, TargetSample

AXES = ("x", "y", "z")

#: the per-axis signal keys, in column order
_AXIS_SIGNALS = tuple(
    (f"mass_{a}_kg", f"damping_{a}_Nspm", f"f_ref_{a}_N", f"sigma_f_{a}_N2") for a in AXES
)


class GPMPC(Controller):
    """Seed B's GP-MPC impedance controller on an admittance-rendering inner loop.

    Args:
        mass_kg: the end-effector mass the robot knows (inertial feed-forward) [kg].
        inner_kp: stiffness of the stiff position loop tracking the admittance [N/m].
        inner_kd: its damping [N s/m].
        rot_stiffness: orientation hold's stiffness [N m/rad].
        rot_damping: orientation hold's damping [N m s/rad].
        init_mass: M at the start of every execution trial (seed B §6.1: the
            low-impedance condition keeps the minimum 5 kg).
        init_damping: D at the start of every execution trial (seed B §6.1: the
            low-impedance condition keeps the minimum 500 N s/m).
        init_f_ref: f^r at the start of a trial [N].
        mpc: settings of :class:`GPMPCProblem` (horizon, ts, bounds, weights, options); or
            ``false`` for the fixed-impedance baseline.
        mpc_period_s: period of the MPC in simulated time [s].
        demo_modes: mode label of each demonstration trial (its length = number of demos).
        demo_mass: M of the admittance rendered during demonstrations.
        demo_damping: D of that admittance.
        demo_f_ref: f^r of that admittance.
        record_every: keep every k-th control step of a demonstration for the GP data.
        gp: keyword arguments of :class:`GPForceModels` (mean, hinge_form, bounds, restarts).
        max_points: at most this many GP training points per mode (evenly thinned).
        min_belief: belief floor of Eq. 12 (0 = pure Bayes).
        force_delay_s: the measured force reaches the admittance loop this late [s]
            (sensor filtering and the robot interface's latency; 0 = the same step).
    """

    def __init__(
        self,
        *,
        mass_kg: float = 1.0,
        inner_kp: float = 2.0e4,
        inner_kd: float = 280.0,
        rot_stiffness: float = 5.0,
        rot_damping: float = 0.5,
        init_mass: Any = 5.0,
        init_damping: Any = 500.0,
        init_f_ref: Any = 0.0,
        mpc: Mapping[str, Any] | bool = True,
        mpc_period_s: float = 0.04,
        demo_modes: Sequence[int] = (0, 0, 0),
        demo_mass: Any = 5.0,
        demo_damping: Any = 500.0,
        demo_f_ref: Any = 0.0,
        record_every: int = 10,
        gp: Mapping[str, Any] | None = None,
        max_points: int = 60,
        min_belief: float = 0.0,
        force_delay_s: float = 0.0,
        key: str = "controller",
    ) -> None:
        self.key = key
        self.mass_kg = check_positive(f"{key}.mass_kg", mass_kg)
        self.inner_kp = check_positive(f"{key}.inner_kp", inner_kp)
        self.inner_kd = check_nonneg(f"{key}.inner_kd", inner_kd)
        self.rot_stiffness = check_nonneg(f"{key}.rot_stiffness", rot_stiffness)
        self.rot_damping = check_nonneg(f"{key}.rot_damping", rot_damping)
        self._raw = {
            "init_mass": init_mass, "init_damping": init_damping, "init_f_ref": init_f_ref,
            "demo_mass": demo_mass, "demo_damping": demo_damping, "demo_f_ref": demo_f_ref,
        }  # fmt: skip
        self._alpha_from_demos = False  # mpc.disturbance.alpha: demonstrations
        self._split_hz = 15.0
        self.mpc_cfg = self._mpc_block(mpc)
        self.mpc_period_s = check_positive(f"{key}.mpc_period_s", mpc_period_s)
        modes = self._demo_modes(demo_modes)
        self.demo_modes = modes
        self.n_modes = max(modes) + 1 if modes else 1
        self._belief_signals = tuple(f"belief_{m}" for m in range(self.n_modes))
        self.record_every = int(check_positive(f"{key}.record_every", record_every))
        self.gp_cfg = dict(gp or {})
        self.max_points = int(check_positive(f"{key}.max_points", max_points))
        self.min_belief = check_nonneg(f"{key}.min_belief", min_belief)
        self.force_delay_s = check_nonneg(f"{key}.force_delay_s", force_delay_s)
        self._data: list[list[np.ndarray]] = [[] for _ in range(self.n_modes)]  # rows [x, f]
        self._demo_force: list[np.ndarray] = []  # this demonstration's measured force (α only)
        self._hf_power: list[np.ndarray] = []  # per demonstration: force power above ω_p
        self.disturbance_alpha: float | None = None  # α̂ of Eq. 16 once estimated
        self._trials_done = 0
        self._problem: Any = None
        self._needs_fit = False  # set by load_state_dict; fitted at the next reset
        self._timing: list[float] = []
        self._iterations: list[int] = []
        self._cpu: list[float] = []  # process CPU time of each solve: robust to a shared machine
        self.dim = 0

    def _mpc_block(self, mpc: Mapping[str, Any] | bool) -> dict[str, Any] | None:
        """The ``mpc`` settings (checked now: one clear error at start-up), {} for the
        defaults, None for no MPC (``false``)."""
        if isinstance(mpc, bool):
            return {} if mpc else None
        if not isinstance(mpc, Mapping):
            raise ConfigError(f"{self.key}.mpc", "must be a mapping of MPC settings or false")
        from ccm.control.mpc.settings import MPCSettings  # casadi: only for the MPC

        cfg = dict(mpc)
        MPCSettings.parse(cfg, f"{self.key}.mpc")
        dist = cfg.get("disturbance") or {}
        self._alpha_from_demos = dist.get("alpha") == "demonstrations"
        self._split_hz = float(dist.get("omega_p", 2 * np.pi * 15)) / (2 * np.pi)
        return cfg

    def _demo_modes(self, demo_modes: Sequence[int]) -> list[int]:
        """The mode label of each demonstration: 0..N-1, each used (none without an MPC)."""
        modes = [int(m) for m in demo_modes] if self.mpc_cfg is not None else []
        key = f"{self.key}.demo_modes"
        if self.mpc_cfg is not None and not modes:
            raise ConfigError(key, "needs at least one demonstration for the GPs")
        if any(m < 0 for m in modes) or (modes and set(modes) != set(range(max(modes) + 1))):
            raise ConfigError(key, f"labels must be 0..N-1, each used; got {modes}")
        return modes

    # ---------------------------------------------------------------- life cycle
    @property
    def demonstrating(self) -> bool:
        """True while the current trial is a demonstration."""
        return self.mpc_cfg is not None and self._trials_done < len(self.demo_modes)

    def _vec(self, name: str) -> np.ndarray:
        return vector(f"{self.key}.{name}", self._raw[name], self.dim)

    def reset(self, dim: int, control_dt: float) -> None:
        super().reset(dim, control_dt)
        if self._needs_fit:
            self._needs_fit = False
            self._fit()
        stage = "demo" if self.demonstrating else "init"
        names = [f"{stage}_{name}" for name in ("mass", "damping", "f_ref")]
        self.mass, self.damping, self.f_ref = (self._vec(name) for name in names)
        if np.any(self.mass <= 0.0):
            raise ConfigError(f"{self.key}.{names[0]}", f"must be > 0, got {self.mass.tolist()}")
        if np.any(self.damping < 0.0):
            raise ConfigError(
                f"{self.key}.{names[1]}", f"must be >= 0, got {self.damping.tolist()}"
            )
        self.belief = np.full(self.n_modes, 1.0 / self.n_modes)
        self.sigma_f = np.full(dim, np.nan)  # Σ^f at ξ_{t+H} of the last solve (none yet)
        self._x_ref: np.ndarray | None = None
        self._v_ref = np.zeros(dim)
        self._theta0 = 0.0
        self._next_mpc = 0.0
        self._step_count = 0
        self._delay_steps = int(round(self.force_delay_s / control_dt))
        self._forces: list[np.ndarray] = []
        self.infeasible = 0
        self.solves = 0
        self._timing = []
        self._iterations = []
        self._cpu = []
        if self._problem is not None:
            self._problem.reset_warm_start()

    def end_trial(self) -> None:
        was_demo = self.demonstrating
        if was_demo and self._alpha_from_demos and len(self._demo_force) > 1:
            from ccm.control.mpc.disturbance_estimate import high_freq_power

            f = np.asarray(self._demo_force)
            self._hf_power.append(high_freq_power(f, self.control_dt, self._split_hz))
        self._demo_force = []
        self._trials_done += 1
        if was_demo and not self.demonstrating:
            self._fit()

    # ---------------------------------------------------------------- models
    def _fit(self) -> None:
        """Fit one GP set per mode from the demonstrations and build Eq. 13 (seed B §3.1.1)."""
        from ccm.control.mpc.problem import GPMPCProblem
        from ccm.learn.gp.gp_force_models import GPForceModels

        self.models = []
        for m, rows in enumerate(self._data):
            data = np.asarray(rows, dtype=float)
            if len(data) < 3:
                raise ConfigError(f"{self.key}.demo_modes", f"mode {m} has too few data points")
            idx = np.unique(np.linspace(0, len(data) - 1, self.max_points).round().astype(int))
            gps = GPForceModels(self.dim, key=f"{self.key}.gp", **self.gp_cfg)
            gps.fit(data[idx, : self.dim], data[idx, self.dim :])
            self.models.append(gps)
        cfg = dict(self.mpc_cfg or {})
        if self._alpha_from_demos:  # α of Eq. 16 from the measured force
            from ccm.control.mpc.disturbance_estimate import alpha_from_power

            self.disturbance_alpha = alpha_from_power(self._hf_power)
            cfg["disturbance"] = {**cfg["disturbance"], "alpha": self.disturbance_alpha}
        self._problem = GPMPCProblem(
            [g.casadi_functions() for g in self.models], self.dim, key=f"{self.key}.mpc", **cfg,
        )  # fmt: skip

    # ---------------------------------------------------------------- control
    def step(self, obs: Observation, target: TargetSample) -> Command:
        """Inner admittance loop at the control rate; the MPC and Eq. 12 at ``mpc_period_s``."""
        dt = self.control_dt
        if self._x_ref is None:
            self._x_ref = obs.position.copy()
            self._v_ref = obs.lin_vel.copy()
            self._theta0 = float(obs.orientation[0]) if obs.orientation.size == 1 else 0.0
        if self.demonstrating:
            if self._alpha_from_demos:
                self._demo_force.append(obs.force.copy())
            if self._step_count % self.record_every == 0:
                mode = self.demo_modes[self._trials_done]
                self._data[mode].append(np.concatenate([obs.position, obs.force]))
        elif self._problem is not None and obs.t + 1e-9 >= self._next_mpc:
            self._next_mpc += self.mpc_period_s
            self._mpc_step(obs)
        # Eq. 4 rendered with backward Euler at the control rate: (M + dt D) v⁺ = M v + dt (f − f^r)
        m, d = self.mass, self.damping
        self._forces.append(obs.force.copy())  # the step objects may be reused (issue #40)
        f_loop = self._forces.pop(0) if len(self._forces) > self._delay_steps else self._forces[0]
        v_new = (m * self._v_ref + dt * (f_loop - self.f_ref)) / (m + dt * d)
        a_ref = (v_new - self._v_ref) / dt
        self._v_ref = v_new
        self._x_ref = self._x_ref + dt * v_new
        force = (
            self.mass_kg * a_ref
            + self.inner_kp * (self._x_ref - obs.position)
            + self.inner_kd * (self._v_ref - obs.lin_vel)
        )
        torque = np.zeros(obs.ang_vel.shape)
        if obs.orientation.size == 1:
            torque[0] = -self.rot_stiffness * (obs.orientation[0] - self._theta0) - (
                self.rot_damping * obs.ang_vel[0]
            )
        self._step_count += 1
        return Command(force=force, torque=torque)

    def _mpc_step(self, obs: Observation) -> None:
        from ccm.control.mpc.terms import belief_update

        if self.n_modes > 1:  # Eq. 12 from the measured force at the measured pose
            preds = [g.predict(obs.position[None, :]) for g in self.models]
            means = np.array([p[0][0] for p in preds])
            variances = np.array([p[1][0] for p in preds])
            noise = np.array([[gm.noise_var_ for gm in g.models] for g in self.models])
            self.belief = belief_update(
                self.belief, obs.force, means, variances + noise, min_belief=self.min_belief
            )
        xi = np.concatenate([obs.position, obs.lin_vel])
        t0, c0 = time.perf_counter(), time.process_time()
        sol = self._problem.solve(xi, self.belief, self.mass, self.damping, self.f_ref)
        self._timing.append(time.perf_counter() - t0)
        self._cpu.append(time.process_time() - c0)
        self._iterations.append(sol.iterations)
        self.solves += 1
        self.sigma_f = self._terminal_variance(sol.predicted)
        if sol.success:
            self.f_ref, self.mass, self.damping = sol.f_ref, sol.mass, sol.damping
        else:  # keep the last feasible command (issue #7 acceptance) and count the event
            self.infeasible += 1

    def _terminal_variance(self, predicted: np.ndarray) -> np.ndarray:
        """Σ^f that the solve saw at its plan's last point ξ_{t+H} (where Eq. 18 is imposed,
        seed B §4.3.1), per axis: each mode's GP variance there, as the problem scales it
        (``gp_var_scale``), averaged with the belief as weight."""
        scale = self._problem.settings.gp_var_scale
        var = [
            g.predict(predicted[m, -1, None, : self.dim])[1][0] for m, g in enumerate(self.models)
        ]
        return scale * (self.belief @ np.asarray(var))

    # ---------------------------------------------------------------- reporting
    def signals(self) -> dict[str, float]:
        """``mass_<axis>_kg``, ``damping_<axis>_Nspm``, ``f_ref_<axis>_N`` per axis (the MPC's
        last accepted output), ``sigma_f_<axis>_N2`` (the GP variance Σ^f that the last solve
        saw at ξ_{t+H}; NaN before the first solve), ``belief_<m>`` per mode,
        ``mpc_infeasible``, ``demonstration``."""
        out: dict[str, float] = {}
        values = zip(
            self.mass.tolist(), self.damping.tolist(), self.f_ref.tolist(),
            self.sigma_f.tolist(), strict=True,
        )  # fmt: skip
        for (k_m, k_d, k_f, k_s), (m, d, f, sf) in zip(_AXIS_SIGNALS, values, strict=False):
            out[k_m], out[k_d], out[k_f], out[k_s] = m, d, f, sf
        for k, b in zip(self._belief_signals, self.belief.tolist(), strict=True):
            out[k] = b
        out["mpc_infeasible"] = float(getattr(self, "infeasible", 0))
        out["demonstration"] = 1.0 if self.demonstrating else 0.0
        return out

    def report(self) -> dict[str, Any]:
        """Solve counts for metrics; wall-clock solve times under ``timing`` (not in
        summary.json, which must be identical run to run)."""
        return {
            "mpc_solves": getattr(self, "solves", 0),
            "mpc_infeasible": getattr(self, "infeasible", 0),
            "demonstration": self.demonstrating,
            "belief": getattr(self, "belief", np.ones(1)).tolist(),
            "disturbance_alpha": self.disturbance_alpha,
            "timing": {
                "mpc_solve_s": list(self._timing),
                "mpc_solve_cpu_s": list(self._cpu),
                "mpc_iterations": list(self._iterations),
            },
        }

    def state_dict(self) -> dict[str, Any] | None:
        """The demonstration data per mode, the per-demonstration high-frequency force power
        (α of Eq. 16) and the number of trials done (JSON; the GPs are refitted
        deterministically from it on load)."""
        return {
            "trials_done": self._trials_done,
            "data": [np.asarray(rows).tolist() for rows in self._data],
            "hf_power": [np.asarray(p).tolist() for p in self._hf_power],
        }

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        try:
            data = [[np.asarray(r, dtype=float) for r in rows] for rows in state["data"]]
            done = int(state["trials_done"])
            hf_power = [np.asarray(p, dtype=float) for p in state.get("hf_power", [])]
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(f"{self.key}.learned_state", f"malformed: {exc}") from None
        if len(data) != self.n_modes:
            raise ConfigError(
                f"{self.key}.learned_state", f"has {len(data)} modes, expected {self.n_modes}"
            )
        self._data, self._trials_done, self._hf_power = data, done, hf_power
        self._problem = None
        self._needs_fit = self.mpc_cfg is not None and done >= len(self.demo_modes)
