"""MkDocs hooks: put the repository's README.md, BENCHMARKS.md and model cards into the site.

The Markdown sources stay readable on GitHub, where ``docs/api.md`` links to ``../README.md`` and
the README links to ``docs/api.md``. MkDocs only sees ``docs/``, so this hook

- adds the repository files below as pages of the site (``overview.md`` etc.), and
- rewrites each page's links from repository paths to site paths before MkDocs checks them.

A link to a repository file that is not a page (``examples/``, ``benches/x.py``) becomes plain
text naming that path; a link to a path that does not exist anywhere is left alone, so
``mkdocs build --strict`` still fails on it.

``SphinxRoles`` (a griffe extension, named in mkdocs.yml) shows the docstrings' Sphinx roles,
``:func:`remove_markers```, as code, ``remove_markers``, in the API reference.
"""

from __future__ import annotations

import posixpath
import re
from pathlib import Path
from typing import Any

import griffe
from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parent

# Repository file -> its page in the site (paths relative to the repository root / docs/).
EXTRA_PAGES = {
    "README.md": "overview.md",
    "BENCHMARKS.md": "benchmarks.md",
    "python/tacswitch/models/MODEL_CARD_motion.md": "model-cards/motion.md",
    "python/tacswitch/models/MODEL_CARD_slip.md": "model-cards/slip.md",
    "python/tacswitch/models/MODEL_CARD_tacdiff.md": "model-cards/tacdiff.md",
}
ROLE = re.compile(r":(?:func|class|meth|mod|data|attr|obj|exc):`~?([^`]+)`")
LINK = re.compile(r"(\]\()([^)\s]+)(\))")
FENCE = re.compile(r"^(```|~~~)")


def on_files(files: Files, config: Any) -> Files:
    """Adds the repository pages of EXTRA_PAGES to the site."""
    for repo_path, site_path in EXTRA_PAGES.items():
        files.append(File.generated(config, site_path,
                                    content=(ROOT / repo_path).read_text(encoding="utf-8")))
    return files


def _repo_path(page_src: str) -> str:
    """The repository path of the page whose site path is ``page_src``."""
    for repo_path, site_path in EXTRA_PAGES.items():
        if site_path == page_src:
            return repo_path
    return f"docs/{page_src}"


def _site_path(repo_path: str) -> str | None:
    """The site path of a repository file, or None when it is not a page of the site."""
    if repo_path in EXTRA_PAGES:
        return EXTRA_PAGES[repo_path]
    if repo_path.startswith("docs/") and (ROOT / repo_path).is_file():
        return repo_path[len("docs/"):]
    return None


def _rewrite(target: str, page_repo: str, page_site: str) -> str | None:
    """The site link for a repository-relative ``target`` of a page; None: make it plain text."""
    if re.match(r"[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
        return target  # a URL or an anchor on the same page
    path, sep, anchor = target.partition("#")
    repo_target = posixpath.normpath(posixpath.join(posixpath.dirname(page_repo), path))
    site_target = _site_path(repo_target)
    if site_target is None:
        if (ROOT / repo_target).exists():
            return None
        return target  # missing everywhere: leave it for MkDocs to report
    rel = posixpath.relpath(site_target, posixpath.dirname(page_site) or ".")
    return rel + sep + anchor


def on_page_markdown(markdown: str, page: Any, config: Any, files: Files) -> str:
    """Rewrites the links of a page from repository paths to site paths (code blocks untouched)."""
    page_site = page.file.src_uri
    page_repo = _repo_path(page_site)
    out: list[str] = []
    in_fence = False
    for line in markdown.splitlines(keepends=True):
        if FENCE.match(line.lstrip()):
            in_fence = not in_fence
        if in_fence:
            out.append(line)
            continue
        out.append(_rewrite_links(line, page_repo, page_site))
    return "".join(out)


def _rewrite_links(line: str, page_repo: str, page_site: str) -> str:
    """One line's ``[text](target)`` links rewritten; repository-only targets become text."""
    result = []
    pos = 0
    for m in LINK.finditer(line):
        new = _rewrite(m.group(2), page_repo, page_site)
        if new is None:
            # "[examples/](examples/)" -> "examples/ (in the repository)": drop "](...)" and the
            # opening bracket that belongs to it.
            start = line.rfind("[", pos, m.start())
            if start < 0:
                continue
            text = line[start + 1:m.start()]
            result.append(line[pos:start])
            if text.strip("`") == m.group(2):
                result.append(f"`{m.group(2)}` (in the repository)")
            else:
                result.append(f"{text} (`{m.group(2)}` in the repository)")
        else:
            result.append(line[pos:m.start()])
            result.append(m.group(1) + new + m.group(3))
        pos = m.end()
    result.append(line[pos:])
    return "".join(result)


class SphinxRoles(griffe.Extension):
    """Docstrings' ``:func:`x```-style roles as code ``x`` (mkdocstrings shows them raw)."""

    def on_instance(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = ROLE.sub(r"`\1`", obj.docstring.value)
