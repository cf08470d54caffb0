"""The documentation site (issue #43): ``mkdocs build --strict`` of the repository's site
passes and holds the pages it should, a broken link fails it, and the hook that brings the
experiment reports into the site (``tools/docs_hooks.py``) rewrites links and lists as its
module docstring says; in a browser the index page shows the theme, navigation and text.
The full build takes ~6 s on 2 cores."""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.browser import chromium, needs_chromium

ROOT = Path(__file__).resolve().parents[1]
MKDOCS = Path(sys.executable).parent / "mkdocs"


def _hooks():
    spec = importlib.util.spec_from_file_location("docs_hooks", ROOT / "tools" / "docs_hooks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _build(config: Path, site: Path) -> subprocess.CompletedProcess[str]:
    if not MKDOCS.exists():
        pytest.fail(f"{MKDOCS} is missing: the dev extra installs mkdocs (make setup)")
    return subprocess.run(
        [str(MKDOCS), "build", "--strict", "-f", str(config), "-d", str(site)],
        cwd=config.parent,
        capture_output=True,
        text=True,
        timeout=300,
    )


def _text(html_file: Path) -> str:
    """The page's text without tags (highlighted code is split into spans)."""
    return re.sub(r"<[^>]+>", "", html_file.read_text(encoding="utf-8"))


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The repository's site, built once in strict mode."""
    out = tmp_path_factory.mktemp("docs") / "site"
    done = _build(ROOT / "mkdocs.yml", out)
    assert done.returncode == 0, done.stderr[-3000:]
    return out


def test_the_site_builds_strict_with_its_pages(site: Path) -> None:
    home = _text(site / "index.html")
    assert "make run     # set up .venv" in home
    assert "make test    # set up .venv and run the test suite" in home
    api = _text(site / "api" / "mixtures" / "index.html")
    assert "ccm.learn.mixtures.igmm" in api
    assert "IGMM" in api and "GMRConditional" in api
    # the reports of experiments/ are pages, the claim map among them
    assert "Claim map" in _text(site / "experiments" / "index.html")
    assert (site / "experiments" / "tuning" / "avic" / "index.html").exists()
    # a repository link from docs/ to experiments/ is a link between the two pages
    simulators = (site / "user-guide" / "simulators" / "index.html").read_text(encoding="utf-8")
    assert 'href="../../experiments/cross_engine/"' in simulators


@needs_chromium
def test_the_index_page_renders_in_a_browser(site: Path, tmp_path: Path) -> None:
    """Headless Chromium opens the built index page from disk: the theme's stylesheet loads
    (material's indigo header band, #4051b5, across the top), the navigation and the page's
    text are drawn (ink on a tenth of the page, measured 12 %). Without the stylesheets the
    header is white and the test fails (checked by hand)."""
    import matplotlib.image as mpimg

    shot = tmp_path / "index.png"
    res = chromium(tmp_path, f"--screenshot={shot}", "--window-size=1280,900",
                   (site / "index.html").as_uri())  # fmt: skip
    assert res.returncode == 0 and shot.is_file(), res.stderr[-2000:]
    img = mpimg.imread(shot)[..., :3]
    assert img.shape[:2] == (900, 1280)
    header = np.median(img[5:40].reshape(-1, 3), axis=0)
    np.testing.assert_allclose(header, [0x40 / 255, 0x51 / 255, 0xB5 / 255], atol=0.03)
    ink = np.mean(np.any(img[60:] < 0.9, axis=2))
    assert ink > 0.05, f"the page looks blank below the header ({ink:.3f} inked)"
    nav = np.mean(np.any(img[100:800, 40:260] < 0.6, axis=2))
    assert nav > 0.02, f"no navigation column drawn ({nav:.3f} inked)"


def test_a_link_to_a_missing_page_fails_the_strict_build(tmp_path: Path) -> None:
    """A small site with the same hook: the report's link to a repository file that is no
    page is rewritten, its link to a page that does not exist is left to fail the build."""
    (tmp_path / "docs").mkdir()
    (tmp_path / "experiments").mkdir()
    (tmp_path / "claims.yaml").write_text("claims: []\n", encoding="utf-8")
    (tmp_path / "docs" / "index.md").write_text(
        "# Home\n\n[the report](../experiments/note.md)\n", encoding="utf-8"
    )
    (tmp_path / "experiments" / "note.md").write_text(
        "# Note\n\nThe claims: [claims.yaml](../claims.yaml); see [home](../docs/index.md).\n",
        encoding="utf-8",
    )
    config = tmp_path / "mkdocs.yml"
    config.write_text(
        f"site_name: t\nhooks:\n  - {ROOT / 'tools' / 'docs_hooks.py'}\n"
        "validation:\n  anchors: warn\n",
        encoding="utf-8",
    )
    done = _build(config, tmp_path / "site")
    assert done.returncode == 0, done.stderr[-3000:]
    note = (tmp_path / "site" / "experiments" / "note" / "index.html").read_text("utf-8")
    assert "<code>claims.yaml</code>" in note and 'href="../.."' in note

    (tmp_path / "experiments" / "note.md").write_text(
        "# Note\n\nSee [the other note](other.md).\n", encoding="utf-8"
    )
    done = _build(config, tmp_path / "site")
    assert done.returncode != 0
    assert "other.md" in done.stderr


@pytest.mark.parametrize(
    ("page_repo", "page_site", "link", "expected"),
    [
        # docs -> experiments, out of docs/ in the repository, a sibling folder in the site
        (
            "docs/user-guide/x.md",
            "user-guide/x.md",
            "[h4](../../experiments/h4.md#anchor)",
            "[h4](../experiments/h4.md#anchor)",
        ),
        # experiments -> docs
        (
            "experiments/README.md",
            "experiments/README.md",
            "[r](../docs/user-guide/reproducing.md)",
            "[r](../user-guide/reproducing.md)",
        ),
        # within experiments: unchanged
        (
            "experiments/README.md",
            "experiments/README.md",
            "[a](tuning/avic.md)",
            "[a](tuning/avic.md)",
        ),
        # a repository file that is no page: its path as code
        (
            "experiments/h1.md",
            "experiments/h1.md",
            "[claims.yaml](claims.yaml)",
            "`experiments/claims.yaml`",
        ),
        (
            "experiments/h1.md",
            "experiments/h1.md",
            "[the code](../ccm/cli.py)",
            "the code (`ccm/cli.py`)",
        ),
        # missing, a URL, an anchor: left to mkdocs
        ("experiments/h1.md", "experiments/h1.md", "[x](nowhere.md)", "[x](nowhere.md)"),
        (
            "docs/index.md",
            "index.md",
            "[u](https://example.org/a.md)",
            "[u](https://example.org/a.md)",
        ),
        ("docs/index.md", "index.md", "[a](#top)", "[a](#top)"),
    ],
)
def test_links_are_rewritten_for_the_site(
    page_repo: str, page_site: str, link: str, expected: str
) -> None:
    out = _hooks().site_markdown(f"see {link}.", page_repo, page_site, "docs", ROOT)
    assert out == f"see {expected}."


def test_links_in_code_are_left_alone() -> None:
    md = "```\n[claims.yaml](claims.yaml)\n```"
    assert _hooks().site_markdown(md, "experiments/h1.md", "experiments/h1.md", "docs", ROOT) == md


def test_github_lists_are_laid_out_for_python_markdown() -> None:
    gfm = _hooks().gfm_lists
    # a list right under a paragraph gets its blank line; nesting by 2 becomes nesting by 4
    assert gfm(["Text:", "* a", "  * b", "* c"]) == ["Text:", "", "* a", "    * b", "* c"]
    # an item's continuation paragraph and fence move with it
    assert gfm(["1. a", "", "   more", "   ```", "   x", "   ```"]) == [
        "1. a",
        "",
        "    more",
        "    ```",
        "    x",
        "    ```",
    ]
    # a wrapped line that starts with a number is no list; text outside lists is unchanged
    assert gfm(["Para ends on", "2018. more text"]) == ["Para ends on", "2018. more text"]
    assert gfm(["    indented code", "# Heading", "text"]) == [
        "    indented code",
        "# Heading",
        "text",
    ]
