"""The figure writer (``ccm.core.records.save_figure``): one draw and one PNG encode give the
pixels ``savefig`` gives, RGB for an opaque figure and RGBA for a transparent one."""

from __future__ import annotations

import io
from pathlib import Path

import matplotlib
import numpy as np
from PIL import Image

from ccm.core.records import save_figure

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)


def _figure(transparent: bool) -> plt.Figure:
    fig, ax = plt.subplots(figsize=(3, 2))
    t = np.linspace(0.0, 1.0, 200)
    ax.plot(t, np.sin(6 * t), label="sin")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("value [1]")
    ax.legend()
    if transparent:
        fig.patch.set_alpha(0.0)
        ax.patch.set_alpha(0.0)
    return fig


def _savefig_pixels(transparent: bool, dpi: int) -> np.ndarray:
    fig = _figure(transparent)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, dpi=dpi, format="png")
    plt.close(fig)
    return np.asarray(Image.open(buf).convert("RGBA"))


def test_pixels_match_savefig(tmp_path: Path) -> None:
    for transparent, mode in ((False, "RGB"), (True, "RGBA")):
        path = tmp_path / f"fig_{transparent}.png"
        save_figure(_figure(transparent), path, dpi=90)
        image = Image.open(path)
        assert image.mode == mode
        assert image.size == (270, 180)  # 3 x 2 in at 90 dpi
        np.testing.assert_array_equal(
            np.asarray(image.convert("RGBA")), _savefig_pixels(transparent, 90)
        )
    assert not list(tmp_path.glob(".*.tmp"))  # no temporary file left behind
