"""The report's "Animations" section: the clips the runs under DIR hold (issue #22).

A run made with ``experiment.animate: first_last``, or animated afterwards with ``ccm animate``
into its own ``animations/<condition>/trial_NNN.{mp4,gif}``, has clips; the report shows them
per run and condition: in report.html a GIF as ``<img>`` and an MP4 as ``<video>``, both
embedded as base64 (the page stays self-contained) up to :data:`EMBED_LIMIT` bytes each and
linked by relative path above it; in report.md as an image or a ``<video>`` tag with the
relative path.
"""

from __future__ import annotations

import base64
import html
from collections.abc import Sequence
from pathlib import Path
from typing import Any

#: bytes: a larger clip is linked, not embedded (chosen: a 2 s 640x480 GIF is ~1-3 MB)
EMBED_LIMIT = 8_000_000
_MIME = {".gif": "image/gif", ".mp4": "video/mp4"}


def clips(run: Path) -> list[Path]:
    """The run's clips, sorted by condition and trial."""
    found = (run / "animations").glob("*/trial_*")
    return sorted(p for p in found if p.suffix.lower() in _MIME and p.is_file())


def _html_clip(path: Path, rel: str) -> str:
    """``<img>`` (GIF) or ``<video>`` (MP4), embedded or, past the limit, linked."""
    kind = _MIME[path.suffix.lower()]
    if path.stat().st_size <= EMBED_LIMIT:
        src = f"data:{kind};base64,{base64.b64encode(path.read_bytes()).decode()}"
    else:
        src = html.escape(rel)
    if kind == "image/gif":
        return f"<img alt='{html.escape(rel)}' src='{src}'>"
    return f"<video controls muted loop preload='metadata' src='{src}'></video>"


def animations_section(
    root: Path, runs: Sequence[tuple[Path, dict[str, Any]]]
) -> tuple[list[str], list[str]]:
    """(markdown lines, html lines) of the Animations section; empty when no run has clips."""
    md: list[str] = []
    hb: list[str] = []
    for run, summary in runs:
        found = clips(run)
        if not found:
            continue
        name = f"{summary.get('experiment', '?')}, seed {summary.get('seed', '?')}"
        md += [f"### {name} (`{run}`)", ""]
        hb.append(f"<h3>{html.escape(name)} <code>{html.escape(str(run))}</code></h3><div>")
        for path in found:
            rel = str(path.relative_to(root)) if path.is_relative_to(root) else str(path)
            label = f"{path.parent.name}, {path.stem.replace('_', ' ')}"
            if path.suffix.lower() == ".gif":
                md.append(f"![{label}]({rel})")
            else:
                md.append(f'<video src="{rel}" controls width="480"></video> {label}')
            hb.append(
                f"<figure style='display:inline-block;margin:4px'>{_html_clip(path, rel)}"
                f"<figcaption>{html.escape(label)}</figcaption></figure>"
            )
        md.append("")
        hb.append("</div>")
    if not md:
        return [], []
    return ["", "## Animations", "", *md], ["<h2>Animations</h2>", *hb]
