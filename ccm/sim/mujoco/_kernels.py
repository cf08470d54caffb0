"""Compiled per-physics-step loop of the MuJoCo backend: the tool's contact ground truth over
MuJoCo's contact list (the readable description is :meth:`ccm.sim.mujoco.robot.MjPanda.
contact_truth`; ``tests/test_mujoco_backend.py`` checks it against the F/T reading and the
contact forces MuJoCo's ``mj_contactForce`` gives). A handful of contacts: plain loops."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def contact_truth(
    geom: np.ndarray,
    efc_address: np.ndarray,
    efc_force: np.ndarray,
    frame: np.ndarray,
    pos: np.ndarray,
    tool_geom: int,
    is_box: np.ndarray,
    friction: np.ndarray,
    tip: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tool's contact truth from MuJoCo's contacts (elliptic cones: a contact's
    ``efc_force`` rows are its normal and two tangential forces on its second geom, in its
    frame, whose rows are the normal and the tangents).

    Args:
        geom: the contacts' geom pairs (n, 2); efc_address: their first constraint row (n,),
            −1 if inactive; efc_force: the constraint forces; frame: (n, 9); pos: (n, 3).
        tool_geom: the tool's geom id; is_box: per geom, whether it is a scene box (wall);
            friction: per contact, its sliding friction (n,); tip: the tool point [m] (3,).

    Returns:
        ``(out, table_pos, table_fn)``: ``out`` = (force on the tool (3), moment about
        ``tip`` (3), count, friction of the contact with the largest normal force (−1 if
        none), table normal, box normal, |box friction|, normal part x, y, z) (14,); the
        table contacts' positions (k, 3) and normal forces (k,).
    """
    out = np.zeros(14)
    out[7] = -1.0
    n = geom.shape[0]
    table_pos = np.zeros((n, 3))
    table_fn = np.zeros(n)
    k, best = 0, -1.0
    bx = by = bz = 0.0
    for i in range(n):
        a = efc_address[i]
        if a < 0 or (geom[i, 0] != tool_geom and geom[i, 1] != tool_geom):
            continue
        s = 1.0 if geom[i, 1] == tool_geom else -1.0
        other = geom[i, 0] if s > 0 else geom[i, 1]
        fn, f1, f2 = efc_force[a], s * efc_force[a + 1], s * efc_force[a + 2]
        f = np.empty(3)
        for j in range(3):
            f[j] = s * fn * frame[i, j] + f1 * frame[i, 3 + j] + f2 * frame[i, 6 + j]
            out[j] += f[j]
            out[11 + j] += s * fn * frame[i, j]
        rx, ry, rz = pos[i, 0] - tip[0], pos[i, 1] - tip[1], pos[i, 2] - tip[2]
        out[3] += ry * f[2] - rz * f[1]
        out[4] += rz * f[0] - rx * f[2]
        out[5] += rx * f[1] - ry * f[0]
        out[6] += 1.0
        if is_box[other]:
            out[9] += fn
            bx += f[0] - s * fn * frame[i, 0]
            by += f[1] - s * fn * frame[i, 1]
            bz += f[2] - s * fn * frame[i, 2]
        else:
            out[8] += fn
            table_pos[k] = pos[i]
            table_fn[k] = fn
            k += 1
        if fn > best:
            best, out[7] = fn, friction[i]
    out[10] = np.sqrt(bx * bx + by * by + bz * bz)
    return out, table_pos[:k], table_fn[:k]


@njit(cache=True)
def tool_state(
    com: np.ndarray,
    quat_wxyz: np.ndarray,
    velocity: np.ndarray,
    rot_now: np.ndarray,
    rot_read: np.ndarray,
    raw: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The tool's centre-of-mass state and F/T reading as :func:`ccm.sim._kernels.tool_sense`
    takes them, from MuJoCo's arrays.

    Args:
        com: the F/T site's (the tool's centre of mass) position (3,); quat_wxyz: the tool's
            orientation (w, x, y, z); velocity: the site's ``mj_objectVelocity`` (ω, v) (6,).
        rot_now: the site's orientation matrix now (9,); rot_read: at the reading (9,).
        raw: the force and torque sensors' reading (6,), in the site frame at the reading.

    Returns:
        ``(link, reading)``: position, orientation (x, y, z, w), linear and angular velocity
        (13,); the reading in the current tool frame (6,) (``Rₙᵀ R_r raw``).
    """
    link = np.empty(13)
    link[:3] = com
    link[3], link[4], link[5], link[6] = quat_wxyz[1], quat_wxyz[2], quat_wxyz[3], quat_wxyz[0]
    link[7:10] = velocity[3:]
    link[10:] = velocity[:3]
    reading = np.empty(6)
    for part in range(2):
        world = np.zeros(3)
        for i in range(3):
            for k in range(3):
                world[i] += rot_read[3 * i + k] * raw[3 * part + k]
        for i in range(3):
            reading[3 * part + i] = (rot_now[i] * world[0] + rot_now[3 + i] * world[1]
                                     + rot_now[6 + i] * world[2])  # fmt: skip
    return link, reading
