"""mkdocs hooks of the documentation site (issue #43; ``hooks:`` in mkdocs.yml).

The experiment reports stay in ``experiments/``, where the report, ``claims.yaml`` and the
tests name them: :func:`on_files` adds every ``experiments/**/*.md`` to the site under
``experiments/`` as a generated file that reads the original, so nothing is copied into
``docs/``.

Links in the Markdown are written for the repository, so that they also work where the files
are read as they are (on GitHub, in an editor). :func:`on_page_markdown` resolves each
relative link against the page's path in the repository and rewrites those the site lays
out differently:

* a link to a Markdown file in ``docs/`` or ``experiments/`` becomes the relative link
  between the two pages in the site (from ``docs/user-guide/x.md``, the repository's
  ``../../experiments/h4.md`` is the site's ``../experiments/h4.md``);
* a link to another file of the repository (``../ccm/...py``, ``claims.yaml``, a figure
  outside ``docs/``, the repository's README), which is no page of the site, becomes the
  file's repository path as code text;
* a link to a file that does not exist is left as it is, so the strict build fails on it.

The docstrings name other objects with Sphinx roles (``:class:`ccm.control.loop.HybridLoop```),
which mkdocstrings leaves as text: :func:`on_page_content` drops the role and links a full
``ccm.`` path to its entry in the API reference where the site has one.

Lists are written as GitHub reads them, and :func:`gfm_lists` lays them out as Python-Markdown
reads them, so nested items and a list right under a paragraph render as on GitHub.
"""

from __future__ import annotations

import posixpath
import re
from pathlib import Path
from typing import Any

#: repository folders whose Markdown files are pages, and their place in the site
EXTERNAL_DIRS = ("experiments",)

_LINK = re.compile(
    r"(?P<bang>!?)\[(?P<text>[^\]\n]*)\]\((?P<target>[^)\s]+)(?P<title>\s+\"[^\"]*\")?\)"
)
_ITEM = re.compile(r" *(?P<marker>[*+-]|\d+[.)])(?P<gap> +)\S")
_FENCE = re.compile(r"\s*(```|~~~)")
_ROLE = re.compile(r":(?:class|meth|func|mod|attr|data|exc|obj):<code>~?(?P<name>[^<]+)</code>")


def _repo_root(config: Any) -> Path:
    return Path(config["config_file_path"]).resolve().parent


def on_files(files: Any, config: Any) -> Any:
    """Add the Markdown files of :data:`EXTERNAL_DIRS` to the site, read in place."""
    from mkdocs.structure.files import File

    root = _repo_root(config)
    for folder in EXTERNAL_DIRS:
        for path in sorted((root / folder).rglob("*.md")):
            src_uri = path.relative_to(root).as_posix()
            files.append(File.generated(config, src_uri, abs_src_path=str(path)))
    return files


def on_serve(server: Any, config: Any, builder: Any) -> Any:
    """``mkdocs serve``: rebuild when a report in :data:`EXTERNAL_DIRS` changes."""
    for folder in EXTERNAL_DIRS:
        server.watch(str(_repo_root(config) / folder))
    return server


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    """Rewrite the page's repository links for the site and space its lists (module doc)."""
    root = _repo_root(config)
    docs_dir = Path(config["docs_dir"]).resolve().relative_to(root).as_posix()
    page_repo = Path(page.file.abs_src_path).resolve().relative_to(root).as_posix()
    return site_markdown(markdown, page_repo, page.file.src_uri, docs_dir, root)


def on_page_content(html: str, page: Any, config: Any, files: Any) -> str:
    """Sphinx roles in the rendered docstrings: a ``ccm.`` path becomes an optional
    cross-reference (mkdocs-autorefs links it if the API reference has it), the rest code."""
    return _ROLE.sub(_role_ref, html)


def _role_ref(m: re.Match[str]) -> str:
    name = m.group("name")
    code = f"<code>{name}</code>"
    if name.startswith("ccm."):
        return f'<autoref identifier="{name}" optional>{code}</autoref>'
    return code


def site_markdown(markdown: str, page_repo: str, page_site: str, docs_dir: str, root: Path) -> str:
    """The page's Markdown with GitHub's lists and its links rewritten for the site (module doc).

    Args:
        markdown: the page's source.
        page_repo: the page's path in the repository, e.g. ``experiments/h4.md``.
        page_site: its path in the site (mkdocs' ``src_uri``), e.g. ``experiments/h4.md``.
        docs_dir: the docs folder's path in the repository, e.g. ``docs``.
        root: the repository's root.

    Returns:
        The Markdown that mkdocs renders.
    """
    lines = gfm_lists(markdown.split("\n"))
    out: list[str] = []
    fence: str | None = None
    for line in lines:
        opened = _FENCE.match(line)
        if fence is None and not opened:
            line = _LINK.sub(lambda m: _site_link(m, page_repo, page_site, docs_dir, root), line)
        if opened and fence is None:
            fence = opened.group(1)
        elif opened and opened.group(1) == fence:
            fence = None
        out.append(line)
    return "\n".join(out)


def gfm_lists(lines: list[str]) -> list[str]:
    """Lay out GitHub-style lists as Python-Markdown reads them.

    GitHub's Markdown nests a list item, or continues it with a paragraph or a code fence, at
    the column where the parent item's text starts (2 for ``* ``, 3 for ``1. ``), and lets a
    list start right under a paragraph. Python-Markdown nests by 4 spaces and needs a blank
    line before a list. This re-indents the lines inside lists to 4 spaces a level (a fence's
    content moves with it) and inserts that blank line; lines outside lists are unchanged.

    Args:
        lines: the Markdown's lines.

    Returns:
        The lines with the lists re-laid.
    """
    out: list[str] = []
    stack: list[tuple[int, int]] = []  # per open item: its text's column in GFM, in the output
    fence: str | None = None
    shift = 0
    prev_blank = True
    in_item = False  # the current paragraph is a list item's first one
    for line in lines:
        if fence is not None:
            if _FENCE.match(line) and line.strip().startswith(fence):
                fence = None
            out.append(_shifted(line, shift))
            continue
        text = line.lstrip(" ")
        indent = len(line) - len(text)
        if not text:
            out.append(line)
            prev_blank = True
            continue
        item = _ITEM.match(line)
        starts_list = item is not None and (
            prev_blank or bool(stack) or item.group("marker") in ("*", "+", "-", "1.", "1)")
        )
        if text.startswith("#") or (indent == 0 and prev_blank and not starts_list):
            stack.clear()  # a heading, or a paragraph after the list
        new = indent
        if item is not None and starts_list and (stack or indent <= 3):
            while stack and stack[-1][0] > indent:
                stack.pop()  # items this one is not nested in
            if not prev_blank and not in_item and not out[-1].lstrip().startswith(("|", ">")):
                out.append("")  # a list right under a paragraph
            new = stack[-1][1] if stack else 0
            stack.append((indent + len(item.group("marker")) + len(item.group("gap")), new + 4))
        elif stack and indent > 0:
            while len(stack) > 1 and stack[-1][0] > indent:
                stack.pop()
            gfm_col, col = stack[-1]
            if indent >= gfm_col:
                new = col + indent - gfm_col
        opened = _FENCE.match(line)
        if opened:
            fence, shift = opened.group(1), new - indent
        out.append(" " * new + text)
        in_item = starts_list or (in_item and not prev_blank)
        prev_blank = False
    return out


def _shifted(line: str, shift: int) -> str:
    """``line`` moved right by ``shift`` columns (left, if negative, over its spaces only)."""
    if shift >= 0:
        return " " * shift + line
    return line[min(-shift, len(line) - len(line.lstrip(" "))) :]


def _site_link(m: re.Match[str], page_repo: str, page_site: str, docs_dir: str, root: Path) -> str:
    target = m.group("target")
    if re.match(r"[a-zA-Z][a-zA-Z0-9+.-]*:", target) or target.startswith(("#", "/")):
        return m.group(0)  # a URL, an anchor on the page, or a site-absolute path
    path, hash_, anchor = target.partition("#")
    repo_path = posixpath.normpath(posixpath.join(posixpath.dirname(page_repo), path))
    if repo_path.startswith("../") or not (root / repo_path).exists():
        return m.group(0)  # outside the repository, or missing: mkdocs judges it
    site_path = _site_path(repo_path, docs_dir)
    if site_path is None:
        text = m.group("text")
        shown = f"`{repo_path}`"
        if text.strip("`") in (path, repo_path, posixpath.basename(path)):
            return shown
        return f"{text} ({shown})"
    rel = posixpath.relpath(site_path, posixpath.dirname(page_site) or ".")
    title = m.group("title") or ""
    return f"{m.group('bang')}[{m.group('text')}]({rel}{hash_}{anchor}{title})"


def _site_path(repo_path: str, docs_dir: str) -> str | None:
    """Where a repository file is in the site, or None if it is not part of the site."""
    if repo_path.startswith(docs_dir + "/"):
        return repo_path[len(docs_dir) + 1 :]
    if repo_path.endswith(".md") and repo_path.split("/", 1)[0] in EXTERNAL_DIRS:
        return repo_path
    return None
