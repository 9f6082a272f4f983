"""mkdocs hooks: the guide's links to files outside docs/ (the README, benchmark scripts), and the
docstrings' Sphinx roles in the API reference.

The pages are read on GitHub and in a checkout as well as on the site, so they link the repository's files
by relative path (``[bench_sim.py](../benchmarks/bench_sim.py)``). The site holds only docs/: there such a
link would be broken. This hook checks each one against the repository — a target that does not exist is a
warning, which ``mkdocs build --strict`` turns into a failed build — and renders an existing one as its text
(the file's name), not as a link. Links inside docs/ are left to mkdocs' own validation (mkdocs.yml).

The docstrings cite names as Sphinx does (``:func:`merge```, ``:class:`~merger.grid.OccupancyGrid```),
which mkdocstrings renders as text. :func:`sphinx_roles` turns each into an optional cross-reference
(``~``: the last part shown): a link when the name is documented on the site (a dotted name as written, a
bare one as ``merger.NAME``), plain code otherwise — a name the site does not document is not an error.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

log = logging.getLogger("mkdocs.plugins.circsim_links")

LINK = re.compile(r"(?<!!)\[([^\]]+)\]\(([^)\s]+)\)")
FENCE = re.compile(r"^(```|~~~)", re.M)
ROLE = re.compile(r":(?:func|class|meth|mod|attr|data|exc|obj):<code>(~?)([\w.]+)</code>")


def outside_links(markdown: str, page_dir: Path, docs_dir: Path, repo: Path) -> tuple[str, list[str]]:
    """``markdown`` with each relative link that leaves ``docs_dir`` replaced by its text, and the targets
    of those that name no file of ``repo`` (fenced code blocks are left alone)."""
    missing: list[str] = []

    def replace(m: re.Match) -> str:
        text, target = m.group(1), m.group(2)
        if re.match(r"[a-z][a-z0-9+.-]*:", target, re.I) or target.startswith(("#", "/")):
            return m.group(0)
        path = (page_dir / target.split("#")[0]).resolve()
        if path.is_relative_to(docs_dir):
            return m.group(0)
        if not (path.is_relative_to(repo) and path.exists()):
            missing.append(target)
            return m.group(0)
        return text

    parts = FENCE.split(markdown)
    out, in_code, k = [], False, 0
    # re.split with one group alternates text, fence, text, ...: toggle on each fence marker
    while k < len(parts):
        chunk = parts[k]
        out.append(chunk if in_code else LINK.sub(replace, chunk))
        if k + 1 < len(parts):
            out.append(parts[k + 1])
            in_code = not in_code
        k += 2
    return "".join(out), missing


def on_page_markdown(markdown, page, config, files):
    docs_dir = Path(config["docs_dir"]).resolve()
    repo = Path(config["config_file_path"]).resolve().parent
    page_dir = (docs_dir / page.file.src_path).parent
    text, missing = outside_links(markdown, page_dir, docs_dir, repo)
    for target in missing:
        log.warning("Doc file '%s' contains a link '%s' to no file of the repository", page.file.src_path, target)
    return text


def sphinx_roles(html: str) -> str:
    """``:role:<code>name</code>`` (a docstring's Sphinx role as rendered) → an optional autorefs
    cross-reference showing the name (its last part after ``~``)."""

    def replace(m: re.Match) -> str:
        tilde, name = m.group(1), m.group(2)
        identifier = name if "." in name else f"merger.{name}"
        shown = name.rpartition(".")[2] if tilde else name
        return f'<autoref identifier="{identifier}" optional><code>{shown}</code></autoref>'

    return ROLE.sub(replace, html)


def on_page_content(html, page, config, files):
    return sphinx_roles(html)
