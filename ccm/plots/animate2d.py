"""2D animation of a pymunk trial: the scene, the tool, the target and the measured force.

Drawn with matplotlib (Agg) from the run's scene (:class:`ccm.sim.pymunk.scene.SceneSpec`:
surfaces with their friction patches, static boxes, springs, viscous regions, seed B's
compliant walls and the simulated human's goals) and the recorded time series: the tool (its
box at the recorded position), its path so far, the target of P, and the measured F/T force
as an arrow from the tool's centre, at a scale stated in the legend [N per m]. Axes are in
metres, equal aspect, with limits fixed over the whole clip. Nothing is simulated.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np

from ccm.plots.frames import AnimateSettings, frame_steps, nice_scale, overlay_text
from ccm.sim.pymunk.scene import SceneSpec

_TOOL, _TARGET, _FORCE, _PATCH = "tab:orange", "tab:green", "tab:red", "tab:blue"
_DPI = 100
_AXES = (0.12, 0.1, 0.85, 0.8)  # the axes' box in the figure (left, bottom, width, height)


def scene_points(scene: SceneSpec) -> list[tuple[float, float]]:
    """The points the view must show of the static scene (surfaces, boxes, anchors,
    regions, compliant walls' points, human goals) [m]."""
    pts: list[tuple[float, float]] = []
    for s in scene.surfaces:
        pts += [s.a, s.b]
    for b in scene.boxes:
        hx, hy = b.size[0] / 2, b.size[1] / 2
        pts += [(b.center[0] - hx, b.center[1] - hy), (b.center[0] + hx, b.center[1] + hy)]
    pts += [sp.anchor for sp in scene.springs]
    for v in scene.viscous:
        if v.region is not None:
            (cx, cy), (hx, hy) = v.region.center, v.region.half_extents
            pts += [(cx - hx, cy - hy), (cx + hx, cy + hy)]
    pts += [w.point for w in scene.compliant_walls]
    if scene.human is not None:
        pts += list(scene.human.goals)
    return pts


def view_limits(
    log: Mapping[str, np.ndarray], scene: SceneSpec, settings: AnimateSettings
) -> tuple[tuple[float, float], tuple[float, float]]:
    """x and y limits [m] over the whole clip: the tool (with its box), the target and the
    scene, with a 10 % margin, widened to the frame's aspect ratio (equal aspect)."""
    half = np.array(scene.ee.size, dtype=float) / 2.0
    xy = np.column_stack([log["pos_x"], log["pos_y"]])
    txy = np.column_stack([log["target_pos_x"], log["target_pos_y"]])
    pts = [xy - half, xy + half, txy]
    if scene_points(scene):
        pts.append(np.array(scene_points(scene), dtype=float))
    allp = np.vstack(pts)
    lo, hi = np.nanmin(allp, axis=0), np.nanmax(allp, axis=0)
    span = np.maximum(hi - lo, 0.05)
    mid = (lo + hi) / 2.0
    span *= 1.2
    aspect = (_AXES[2] * settings.width) / (_AXES[3] * settings.height)  # the axes' box
    if span[0] / span[1] < aspect:
        span[0] = span[1] * aspect
    else:
        span[1] = span[0] / aspect
    lo, hi = mid - span / 2, mid + span / 2
    return (float(lo[0]), float(hi[0])), (float(lo[1]), float(hi[1]))


def force_scale(log: Mapping[str, np.ndarray], span: float, settings: AnimateSettings) -> float:
    """N per metre of arrow: ``animate.force_scale_N_per_m``, or one that draws the clip's
    95th percentile of the measured force at about a quarter of the view's width (a short
    impact spike may then run longer)."""
    if settings.force_scale_N_per_m is not None:
        return settings.force_scale_N_per_m
    return nice_scale(float(np.nanpercentile(np.hypot(log["force_x"], log["force_y"]), 95)), span)


def _draw_surfaces(ax: Any, scene: SceneSpec) -> None:
    """Static segments, each friction patch in blue with its coefficient below it."""
    for s in scene.surfaces:
        a, b = np.array(s.a, float), np.array(s.b, float)
        u = (b - a) / max(s.length, 1e-12)
        for s0, s1, mu in s.pieces():
            p0, p1 = a + s0 * u, a + s1 * u
            patch = mu != s.friction
            ax.plot(
                [p0[0], p1[0]],
                [p0[1], p1[1]],
                color=_PATCH if patch else "0.2",
                lw=4 if patch else 2.5,
                solid_capstyle="butt",
                zorder=2,
            )
            if patch:
                m = (p0 + p1) / 2
                ax.annotate(
                    f"μ={mu:g}",
                    m,
                    xytext=(0, -11),
                    textcoords="offset points",
                    ha="center",
                    fontsize=7,
                    color=_PATCH,
                )


def _draw_scene(ax: Any, scene: SceneSpec, xlim: tuple[float, float]) -> None:
    """The static scene: surfaces (patches in blue, labelled with their friction), boxes,
    viscous regions (shaded), spring anchors, compliant walls and human goals."""
    from matplotlib.patches import Rectangle

    _draw_surfaces(ax, scene)
    for b in scene.boxes:
        ax.add_patch(
            Rectangle(
                (b.center[0] - b.size[0] / 2, b.center[1] - b.size[1] / 2),
                b.size[0],
                b.size[1],
                color="0.55",
                zorder=2,
            )
        )
    for v in scene.viscous:
        if v.region is None:
            ax.set_facecolor("#eef3fb")
            continue
        (cx, cy), (hx, hy) = v.region.center, v.region.half_extents
        ax.add_patch(Rectangle((cx - hx, cy - hy), 2 * hx, 2 * hy, color="#cfdff5", zorder=0))
    for sp in scene.springs:
        ax.plot(*sp.anchor, marker="s", color="0.3", ms=6, zorder=3)
    for w in scene.compliant_walls:
        n = np.array(w.normal, float) / np.linalg.norm(w.normal)
        d = np.array([-n[1], n[0]]) * 10.0 * (xlim[1] - xlim[0])
        p = np.array(w.point, float)
        ax.plot(
            [p[0] - d[0], p[0] + d[0]],
            [p[1] - d[1], p[1] + d[1]],
            color="tab:brown",
            lw=2.5,
            zorder=2,
        )
    if scene.human is not None:
        g = np.array(scene.human.goals, float)
        ax.plot(g[:, 0], g[:, 1], "P", color="tab:purple", ms=8, zorder=3)


def _legend(ax: Any, scene: SceneSpec, scale: float) -> None:
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    items = [
        Patch(color=_TOOL, label="tool"),
        Line2D([], [], color=_TARGET, marker="x", ls="", label="target (P)"),
        Line2D([], [], color=_FORCE, lw=2, label=f"measured force ({scale:g} N per m)"),
    ]
    if scene.springs:
        items.append(Line2D([], [], color="0.3", ls=":", marker="s", label="spring"))
    if any(v.region is not None for v in scene.viscous):
        items.append(Patch(color="#cfdff5", label="viscous region"))
    if any(s.patches for s in scene.surfaces):
        items.append(Line2D([], [], color=_PATCH, lw=4, label="friction patch"))
    if scene.compliant_walls:
        items.append(Line2D([], [], color="tab:brown", lw=2.5, label="compliant wall"))
    ax.legend(handles=items, loc="upper right", fontsize=7, framealpha=0.85)


def _figure(
    log: Mapping[str, np.ndarray], scene: SceneSpec, settings: AnimateSettings
) -> tuple[Any, Any, float]:
    """The figure with the static scene, axes and legend drawn; returns (figure, its Agg
    canvas, force scale [N per m])."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(settings.width / _DPI, settings.height / _DPI), dpi=_DPI)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes(_AXES)
    xlim, ylim = view_limits(log, scene, settings)
    ax.set(xlim=xlim, ylim=ylim, xlabel="x [m]", ylabel="y [m]")
    ax.set_aspect("equal", adjustable="box")  # the limits already have the box's ratio
    ax.grid(alpha=0.3)
    _draw_scene(ax, scene, xlim)
    scale = force_scale(log, xlim[1] - xlim[0], settings)
    _legend(ax, scene, scale)
    return fig, canvas, scale


def frames_2d(
    log: Mapping[str, np.ndarray],
    scene: SceneSpec,
    settings: AnimateSettings,
    labels: Mapping[str, Any],
) -> Iterator[np.ndarray]:
    """RGB frames (height x width x 3, uint8) of one recorded 2D trial (module docstring);
    ``labels``: ``phase`` and ``segments`` (the pattern's segment names) for the overlay.
    The static figure is drawn once; each frame restores it and draws the moving artists
    on it (blitting: ~5x faster than redrawing the figure)."""
    from matplotlib.patches import FancyArrowPatch, Rectangle

    fig, canvas, scale = _figure(log, scene, settings)
    ax = fig.axes[0]
    w, h = scene.ee.size
    (trail,) = ax.plot([], [], color=_TOOL, lw=1, alpha=0.6)
    springs = [ax.plot([], [], ":", color="0.3", lw=1.2)[0] for _ in scene.springs]
    tool = ax.add_patch(Rectangle((0, 0), w, h, color=_TOOL, alpha=0.85))
    (target,) = ax.plot([], [], "x", color=_TARGET, ms=9, mew=2)
    arrow = ax.add_patch(
        FancyArrowPatch((0, 0), (0, 0), arrowstyle="-|>", mutation_scale=14, color=_FORCE, lw=2)
    )
    text = fig.text(0.01, 0.965, "", fontsize=9, family="monospace", va="top")
    moving = [trail, *springs, tool, target, arrow]  # drawn in this order, over the scene
    for artist in [*moving, text]:
        artist.set_animated(True)
    canvas.draw()
    background = canvas.copy_from_bbox(fig.bbox)
    for k in frame_steps(log["t"], settings.fps):
        x, y = float(log["pos_x"][k]), float(log["pos_y"][k])
        tool.set_xy((x - w / 2, y - h / 2))
        trail.set_data(log["pos_x"][: k + 1], log["pos_y"][: k + 1])
        target.set_data([log["target_pos_x"][k]], [log["target_pos_y"][k]])
        t = float(log["t"][k])
        for line, sp in zip(springs, scene.springs, strict=True):
            on = t >= sp.attach_s and (sp.detach_s is None or t < sp.detach_s)
            line.set_data(*([[sp.anchor[0], x], [sp.anchor[1], y]] if on else [[], []]))
        f = np.array([log["force_x"][k], log["force_y"][k]], dtype=float) / scale
        arrow.set_positions((x, y), (x + f[0], y + f[1]))
        text.set_text(overlay_text(log, k, labels))
        canvas.restore_region(background)
        for artist in moving:
            ax.draw_artist(artist)
        fig.draw_artist(text)
        yield np.asarray(canvas.buffer_rgba())[:, :, :3].copy()
