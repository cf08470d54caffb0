"""Headless Chromium for the tests that look at a page as a reader does (``report.html``, the
documentation site): the executable, its flags for a closed network, and one call.
``make test`` installs Debian's chromium where it can (``make browser``); without it those
tests skip."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
#: a skip mark for the tests that need it
needs_chromium = pytest.mark.skipif(
    CHROMIUM is None, reason="chromium not installed (`make browser` installs it as root)"
)
# flags for a closed network: without the background-networking ones Chromium keeps trying
# to reach Google's hosts at start-up
FLAGS = (
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--hide-scrollbars",
)  # fmt: skip


def chromium(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    """Run headless Chromium with ``args`` and a fresh profile under ``tmp_path``."""
    profile = tmp_path / "profile"
    cmd = [str(CHROMIUM), *FLAGS, f"--user-data-dir={profile}", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=False)
