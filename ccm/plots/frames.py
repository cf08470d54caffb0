"""Frames of an animation, and writing them to MP4 (ffmpeg) or GIF (Pillow).

MP4 needs no system install: the ``imageio-ffmpeg`` dependency ships an ffmpeg binary with
libx264 (issue #43); an ffmpeg on PATH is the fallback.

An animation replays one recorded trial (``timeseries/<condition>/trial_NNN.parquet``) in
real time: frame ``k`` shows the last control step at or before ``t0 + k / fps``, and a clip of
a trial recorded over ``T`` seconds has ``ceil(T fps)`` frames (:func:`frame_steps`). Settings
come from the ``animate`` block of the run's config (``configs/config.yaml``):
:class:`AnimateSettings`.
"""

from __future__ import annotations

import math
import shutil
import subprocess
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ccm.core.errors import (
    ConfigError,
    check_keys,
    check_positive,
    check_range,
    check_vector,
    to_plain,
)
from ccm.core.records import atomic_path

#: clip formats: MP4 through ffmpeg (:func:`ffmpeg`), GIF through Pillow otherwise
FORMATS = (".mp4", ".gif")
_CAMERA_KEYS = ("distance", "yaw", "pitch", "target", "fov")


@dataclass(frozen=True)
class Camera:
    """The 3D view (``animate.camera``): PyBullet's ``computeViewMatrixFromYawPitchRoll``.

    Attributes:
        distance: from the target point [m]; yaw, pitch: [deg] (pitch < 0 looks down);
        target: the point looked at [m], or ``None`` for 0.2 m above the centre of the
            recorded tool path (:mod:`ccm.plots.animate3d`);
        fov: vertical field of view [deg].
    """

    distance: float = 1.5
    yaw: float = 50.0
    pitch: float = -30.0
    target: tuple[float, float, float] | None = None
    fov: float = 50.0


#: frames per second a clip may have (issue #39: ``--fps 1e6`` hung writing a million frames
#: per simulated second). A GIF stores each frame's delay in 1/100 s, so 100 fps is its limit;
#: below 1 fps a clip of a trial is a few stills.
FPS_RANGE = (1.0, 100.0)


@dataclass(frozen=True)
class AnimateSettings:
    """The ``animate`` config block (defaults: the values ``configs/config.yaml`` ships)."""

    fps: float = 25.0
    width: int = 640
    height: int = 480
    force_scale_N_per_m: float | None = None
    camera: Camera = Camera()

    @classmethod
    def from_mapping(
        cls, cfg: Mapping[str, Any] | None, fps: float | None = None
    ) -> AnimateSettings:
        """Validate ``animate`` (missing keys take the defaults; ``fps`` overrides its fps)."""
        d = dict(to_plain(cfg) or {})
        check_keys("animate", d, ("fps", "width", "height", "force_scale_N_per_m", "camera"))
        size = [_even_px(f"animate.{k}", d.get(k, getattr(cls, k))) for k in ("width", "height")]
        scale = d.get("force_scale_N_per_m")
        cam = dict(d.get("camera") or {})
        check_keys("animate.camera", cam, _CAMERA_KEYS)
        target = cam.get("target")
        key = "animate.camera"
        angles = check_vector(
            f"{key}.yaw, pitch", [cam.get(a, getattr(Camera, a)) for a in ("yaw", "pitch")], 2
        )
        camera = Camera(
            distance=check_positive(f"{key}.distance", cam.get("distance", Camera.distance)),
            yaw=float(angles[0]),
            pitch=float(angles[1]),
            target=None if target is None else tuple(check_vector(f"{key}.target", target, 3)),
            fov=check_range(f"{key}.fov", cam.get("fov", Camera.fov), 1.0, 170.0),
        )
        return cls(
            fps=check_range(
                "--fps" if fps is not None else "animate.fps",
                fps if fps is not None else d.get("fps", cls.fps),
                *FPS_RANGE,
            ),
            width=size[0],
            height=size[1],
            force_scale_N_per_m=None
            if scale is None
            else check_positive("animate.force_scale_N_per_m", scale),
            camera=camera,
        )


def _even_px(key: str, value: Any) -> int:
    """A frame side [px]: an even integer from 32 to 4096 (H.264's 4:2:0 needs even sides)."""
    ok = isinstance(value, int) and not isinstance(value, bool) and 32 <= value <= 4096
    if not ok or value % 2:
        raise ConfigError(key, f"must be an even integer from 32 to 4096 [px], got {value!r}")
    return int(value)


def frame_steps(t: np.ndarray, fps: float) -> np.ndarray:
    """Indices of the control steps the frames show: frame ``k`` at ``t[0] + k / fps``
    shows the last step at or before it; ``ceil(T fps)`` frames for a recording of ``T`` s
    (``T`` = steps x the step's length, so 600 steps of 1 ms at 25 fps give 15 frames)."""
    t = np.asarray(t, dtype=float)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0 / fps
    duration = len(t) * dt
    n = max(1, math.ceil(duration * fps - 1e-9))
    times = t[0] + np.arange(n) / fps
    idx = np.searchsorted(t, times + 1e-9, side="right") - 1
    return np.clip(idx, 0, len(t) - 1)


def ffmpeg() -> str | None:
    """The ffmpeg executable: imageio-ffmpeg's bundled binary, else one on PATH, else
    ``None`` (then clips are GIFs)."""
    try:
        import imageio_ffmpeg

        return imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError):  # not installed, or no binary for this platform
        return shutil.which("ffmpeg")


def default_suffix() -> str:
    """``.mp4`` when an ffmpeg is available (:func:`ffmpeg`), else ``.gif``."""
    return ".mp4" if ffmpeg() else ".gif"


def check_out(path: Path) -> Path:
    """``--out``: a ``.mp4`` (needs ffmpeg) or ``.gif`` file in a directory that exists."""
    path = Path(path)
    if path.suffix.lower() not in FORMATS:
        raise ConfigError("--out", f"must end in .mp4 or .gif, got {str(path)!r}")
    if path.suffix.lower() == ".mp4" and ffmpeg() is None:
        raise ConfigError(
            "--out", "an .mp4 needs ffmpeg (pip install imageio-ffmpeg, or one on PATH); use .gif"
        )
    if path.is_dir():
        raise ConfigError("--out", f"{path} is a directory; give a file ending in .mp4 or .gif")
    return path


def write_clip(path: Path, frames: Iterable[np.ndarray], fps: float) -> int:
    """Write RGB uint8 frames (all of one size) to ``path`` (MP4 or GIF by its suffix),
    atomically; return the number of frames."""
    path = Path(path)
    with atomic_path(path) as tmp:
        if path.suffix.lower() == ".mp4":
            return _write_mp4(tmp, frames, fps)
        return _write_gif(tmp, frames, fps)


def _write_mp4(path: Path, frames: Iterable[np.ndarray], fps: float) -> int:
    """H.264 (yuv420p, so any player shows it) through an ffmpeg pipe of raw RGB frames."""
    exe = ffmpeg()
    if exe is None:
        raise ConfigError("--out", "an .mp4 needs ffmpeg (pip install imageio-ffmpeg); use .gif")
    count, proc = 0, None
    try:
        for frame in frames:
            if proc is None:
                h, w = frame.shape[:2]
                proc = subprocess.Popen(  # noqa: S603 - fixed arguments, no shell
                    [
                        exe,
                        "-y",
                        "-loglevel",
                        "error",
                        "-f",
                        "rawvideo",
                        "-pix_fmt",
                        "rgb24",
                        "-s",
                        f"{w}x{h}",
                        "-r",
                        f"{fps:g}",
                        "-i",
                        "-",
                        "-an",
                        "-c:v",
                        "libx264",
                        "-pix_fmt",
                        "yuv420p",
                        "-crf",
                        "23",
                        "-f",
                        "mp4",
                        str(path),
                    ],
                    stdin=subprocess.PIPE,
                    stderr=subprocess.PIPE,
                )
            proc.stdin.write(np.ascontiguousarray(frame, dtype=np.uint8).tobytes())
            count += 1
    finally:
        if proc is not None:
            proc.stdin.close()
            err = proc.stderr.read().decode(errors="replace").strip()
            if proc.wait() != 0:
                raise RuntimeError(f"ffmpeg failed writing {path}: {err.splitlines()[-1:]}")
    return count


def _write_gif(path: Path, frames: Iterable[np.ndarray], fps: float) -> int:
    """An animated GIF (one adaptive palette per frame, looping); GIF delays are in 10 ms
    steps, so e.g. 30 fps plays at 33.3 fps. Frames stream through Pillow one at a time (a
    long trial's clip never sits in memory whole)."""
    from PIL import Image

    def paletted(frame: np.ndarray) -> Any:
        # fast octree: median cut (the default) took 15 s for a 288-frame clip, this 7 s
        image = Image.fromarray(np.asarray(frame, dtype=np.uint8))
        return image.quantize(colors=128, method=Image.Quantize.FASTOCTREE)

    stream = iter(frames)
    first = next(stream, None)
    if first is None:
        raise ValueError("no frames to write")
    count = 1

    def rest() -> Iterator[Any]:
        nonlocal count
        for frame in stream:
            count += 1
            yield paletted(frame)

    paletted(first).save(
        path, format="gif", save_all=True, append_images=rest(), loop=0,
        duration=max(20, round(1000.0 / fps / 10.0) * 10), optimize=False,
    )  # fmt: skip
    return count


def nice_scale(peak: float, span: float) -> float:
    """A force scale [N per m of arrow] from 1-2-5 steps that draws ``peak`` [N] at about a
    quarter of ``span`` [m] (or shorter)."""
    want = max(peak, 1e-3) / max(0.25 * span, 1e-6)
    step = 10.0 ** math.floor(math.log10(want))
    for k in (1.0, 2.0, 5.0, 10.0):
        if k * step >= want:
            return k * step
    return 10.0 * step


def overlay_text(log: Mapping[str, np.ndarray], k: int, labels: Mapping[str, Any]) -> str:
    """The overlay of step ``k``: time [s], the experiment phase, the pattern segment (its
    name where the task gives one) and, where recorded, the detected contact mode and contact."""
    parts = [f"t = {float(log['t'][k]):6.3f} s"]
    if labels.get("phase") not in (None, "main"):
        parts.append(f"phase: {labels['phase']}")
    if "segment" in log:
        seg = int(log["segment"][k])
        names = labels.get("segments") or []
        parts.append(f"segment: {names[seg] if 0 <= seg < len(names) and names[seg] else seg}")
    if "mode" in log and np.isfinite(log["mode"][k]):  # -1: free space or not yet classified
        mode = int(log["mode"][k])
        parts.append(f"mode: {mode if mode >= 0 else 'free/none'}")
    if "truth_contact" in log and np.isfinite(log["truth_contact"][k]):
        parts.append("in contact" if log["truth_contact"][k] > 0 else "free")
    return "   ".join(parts)
