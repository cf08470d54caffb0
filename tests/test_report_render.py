"""``report.html`` renders in a real browser (issue #8 part 3): headless Chromium loads the
self-contained page, takes a screenshot, and the claims table and the embedded figure are
visible in it. ``make test`` installs Debian's chromium where it can (``make browser``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ccm.reporting.report import main
from tests.browser import chromium, needs_chromium

pytestmark = needs_chromium
CLAIMS = """claims:
  - {id: render-claim, paper: seed_b, source: "Fig. 6", statement: "x below y",
     paper_value: "q", experiment: e, compare: less_than, a: {condition: x, metric: m},
     b: {condition: y, metric: m}, figures: [f.png]}
"""


def _red_figure(path: Path) -> None:
    """A figure whose pure-red block is easy to find in a screenshot."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4, 3), dpi=100)
    ax.axvspan(0.2, 0.8, color=(1.0, 0.0, 0.0))
    ax.set(xlabel="time [s]", ylabel="force [N]")
    fig.savefig(path)
    plt.close(fig)


@pytest.fixture
def report(tmp_path: Path) -> Path:
    root = tmp_path / "multirun"
    for seed, (a, b) in enumerate([(1.0, 2.0), (1.2, 2.1), (0.9, 2.0)]):
        d = root / str(seed)
        (d / "figures").mkdir(parents=True)
        summary = {"experiment": "e", "status": "ok", "seed": seed, "trials": [],
                   "conditions": {"x": {"m": a}, "y": {"m": b}}}  # fmt: skip
        (d / "summary.json").write_text(json.dumps(summary), encoding="utf-8")
        if seed == 0:
            _red_figure(d / "figures" / "f.png")
    (tmp_path / "claims.yaml").write_text(CLAIMS, encoding="utf-8")
    assert main([str(root), "--claims", str(tmp_path / "claims.yaml")]) == 0
    return root / "report.html"


def test_report_html_renders_in_headless_chromium(report: Path, tmp_path: Path) -> None:
    shot = tmp_path / "report.png"
    res = chromium(tmp_path, f"--screenshot={shot}", "--window-size=1200,1400", report.as_uri())
    assert res.returncode == 0 and shot.is_file(), res.stderr[-2000:]
    import matplotlib.image as mpimg

    img = mpimg.imread(shot)[..., :3]  # floats in [0, 1]
    assert img.shape[:2] == (1400, 1200)
    ink = np.mean(np.any(img < 0.9, axis=2))
    assert ink > 0.01, f"the page looks blank ({ink:.4f} of the pixels are not white)"
    red = (img[..., 0] > 0.9) & (img[..., 1] < 0.1) & (img[..., 2] < 0.1)
    # the embedded figure's red block is ~240 x 230 px at 100 dpi (scaled by the page's CSS)
    assert red.sum() > 2000, f"the embedded figure did not render ({red.sum()} red pixels)"


def test_report_dom_shows_the_claim_and_verdict(report: Path, tmp_path: Path) -> None:
    res = chromium(tmp_path, "--dump-dom", report.as_uri())
    assert res.returncode == 0, res.stderr[-2000:]
    dom = res.stdout
    assert "render-claim" in dom and "reproduced" in dom
    assert dom.count("<img") >= 1 and "data:image/png;base64," in dom
