"""The MuJoCo Panda's reads and writes for the backend (:mod:`ccm.sim.mujoco.backend`): model
terms of the torque law from MuJoCo's own calls, the tool's state, the wrist F/T reading and
the contact ground truth.

* **Model terms** (at the state :func:`mujoco.mj_step1` just computed): J of the tool point
  site (``mj_jacSite``, [J_v; J_ω] in world axes), J̇ (``mj_jacDot`` at the same point, so
  J̇ q̇ is the tool point's classical acceleration at q̈ = 0), h = ``qfrc_bias`` (gravity +
  Coriolis, no damping or armature in the model) and M⁻¹ (``mj_solveM`` on the factor
  ``mj_step1`` made). ``tests/test_mujoco_backend.py`` checks them against Pinocchio's.
* **F/T reading.** The sensors are computed in :func:`mujoco.mj_step2` *before* it integrates,
  in the tool frame of that moment; :meth:`MjPanda.keep_reading` keeps them with that frame, and
  :meth:`MjPanda.tool_link` expresses them in the next state's tool frame, where
  :func:`ccm.sim._kernels.tool_sense` reads them.
* **Contact truth.** ``efc_force`` of each active contact of the tool geom, in its contact
  frame (normal then the two tangents: the elliptic cone's layout; the force on the
  contact's second geom, measured), rotated to the world and signed for the tool; the
  contact positions and frames are those of the step's collision detection.
"""

from __future__ import annotations

from collections.abc import Collection
from typing import Any

import mujoco
import numpy as np

from ccm.sim.arm import model_terms
from ccm.sim.mujoco import _kernels as _k
from ccm.sim.mujoco.model import ARM_JOINTS, FT_SITE, TOOL_POINT
from ccm.sim.panda import N_ARM

_EMPTY = (np.zeros(3), np.zeros(3), 0, -1.0, np.zeros(6))


class MjPanda:
    """One compiled Panda model and its data, with the ids and buffers the backend uses.

    Args:
        model: the compiled model (:func:`ccm.sim.mujoco.model.panda_spec` plus the world).
        box_geoms: names of the scene's boxes (walls); other static geoms are the table's.
    """

    def __init__(self, model: mujoco.MjModel, box_geoms: Collection[str]) -> None:
        self.model, self.data = model, mujoco.MjData(model)
        if model.nv != N_ARM or [model.joint(i).name for i in range(N_ARM)] != list(ARM_JOINTS):
            raise RuntimeError(f"unexpected Panda joint layout in the MuJoCo model (nv={model.nv})")
        self.tool_body = model.body("ccm_tool").id
        self.tool_geom = int(np.flatnonzero(model.geom_bodyid == self.tool_body)[0])
        self.tip_site, self.ft_site = model.site(TOOL_POINT).id, model.site(FT_SITE).id
        self._is_box = np.zeros(model.ngeom, dtype=np.bool_)
        for name in box_geoms:
            self._is_box[model.geom(name).id] = True
        self.limits = (model.jnt_range[:N_ARM, 0].copy(), model.jnt_range[:N_ARM, 1].copy())
        self._jac, self._jdot = np.zeros((6, N_ARM)), np.zeros((6, N_ARM))
        self._minv, self._eye = np.zeros((N_ARM, N_ARM)), np.eye(N_ARM)
        self._vel = np.zeros(6)
        self._raw = np.zeros(6)
        self._rot_read = np.eye(3).ravel()

    # ------------------------------------------------------------------ kinematics

    def pose(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Move the arm to ``q`` at rest; the tool point's position and orientation
        (x, y, z, w) there (:func:`ccm.sim.arm.dls_ik`'s ``pose``)."""
        m, d = self.model, self.data
        d.qpos[:] = q
        d.qvel[:] = 0.0
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        return d.site_xpos[self.tip_site].copy(), self.orientation()

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """The tool point's Jacobian [J_v; J_ω] (6, 7) at the ``q`` of the last :meth:`pose`."""
        mujoco.mj_jacSite(self.model, self.data, self._jac[:3], self._jac[3:], self.tip_site)
        return self._jac.copy()

    def orientation(self) -> np.ndarray:
        """The tool's orientation (x, y, z, w) (MuJoCo's quaternions are w first)."""
        w, x, y, z = self.data.xquat[self.tool_body]
        return np.array([x, y, z, w])

    # ------------------------------------------------------------------ per physics step

    def terms(self) -> tuple[np.ndarray, ...]:
        """``(J, J̇ q̇, h, M⁻¹ Jᵀ, J M⁻¹ Jᵀ, Λ)`` at the current state (module docstring)."""
        m, d, jac, jdot = self.model, self.data, self._jac, self._jdot
        mujoco.mj_jacSite(m, d, jac[:3], jac[3:], self.tip_site)
        mujoco.mj_jacDot(m, d, jdot[:3], jdot[3:], d.site_xpos[self.tip_site], self.tool_body)
        mujoco.mj_solveM(m, d, self._minv, self._eye)
        return model_terms(self._minv, jac.copy(), jdot @ d.qvel, d.qfrc_bias.copy())

    def tool_link(self) -> tuple[np.ndarray, np.ndarray]:
        """The tool's centre of mass: position, orientation (x, y, z, w), linear and angular
        velocity (13,) as :func:`ccm.sim._kernels.tool_sense` reads them, and the last
        :meth:`keep_reading` in this state's tool frame (6,)
        (:func:`ccm.sim.mujoco._kernels.tool_state`)."""
        m, d, ft = self.model, self.data, self.ft_site
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_SITE, ft, self._vel, 0)
        return _k.tool_state(d.site_xpos[ft], d.xquat[self.tool_body], self._vel,
                             d.site_xmat[ft], self._rot_read, self._raw)  # fmt: skip

    def keep_reading(self) -> None:
        """After :func:`mujoco.mj_step2`: keep the F/T sensors' reading (the hand on the tool,
        the moment about its centre of mass, in the tool frame of that moment) and that
        frame (module docstring)."""
        d = self.data
        self._raw[:] = d.sensordata[:6]
        self._rot_read[:] = d.site_xmat[self.ft_site]

    def contact_truth(
        self, tip: np.ndarray
    ) -> tuple[tuple[np.ndarray, np.ndarray, int, float, np.ndarray], list[tuple[Any, float]]]:
        """After :func:`mujoco.mj_step2`: the tool's contact force, moment about ``tip``,
        count, the sliding friction of the contact carrying the largest normal force and
        ``(table normal, box normal, |box friction|, normal part x, y, z)`` [N]; and the
        table contacts ``(position, normal force)`` for the footprint friction. Each
        active contact of the tool's geom contributes its ``efc_force`` (normal, then the
        two tangential forces on the contact's second geom, in its frame), signed for the
        tool (:func:`ccm.sim.mujoco._kernels.contact_truth`)."""
        d = self.data
        if d.ncon == 0:
            return _EMPTY, []
        con = d.contact
        out, table_pos, table_fn = _k.contact_truth(
            con.geom, con.efc_address, d.efc_force, con.frame, con.pos, self.tool_geom,
            self._is_box, con.friction[:, 0], tip,
        )  # fmt: skip
        truth = (out[:3], out[3:6], int(out[6]), float(out[7]), out[8:])
        return truth, list(zip(table_pos, table_fn.tolist(), strict=True))
