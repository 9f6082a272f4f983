"""The documentation site (mkdocs.yml): a strict build fails on a broken link, anchor or reference, the
guide's links out of docs/ are checked against the repository (docs/hooks/links.py), and the API reference
documents every public name of ``merger``."""

import importlib.util
import re
import subprocess
import sys

import pytest
import yaml

from tests.paths import REPO

HOOK = REPO / "docs" / "hooks" / "links.py"


def hook():
    spec = importlib.util.spec_from_file_location("site_links", HOOK)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_links_out_of_docs_become_text_and_missing_ones_are_named(tmp_path):
    docs = tmp_path / "docs"
    (docs / "design").mkdir(parents=True)
    (tmp_path / "benchmarks").mkdir()
    (tmp_path / "benchmarks" / "bench.py").write_text("")
    md = ("See [bench.py](../../benchmarks/bench.py), [the README](../../README.md#set-up), "
          "[search](search.md#x), [site](https://example.org/a.md), ![img](../../img.png) and [top](#top).\n"
          "```sh\n[kept](../../benchmarks/bench.py)\n```\nafter [again](../../benchmarks/bench.py)\n")
    text, missing = hook().outside_links(md, docs / "design", docs.resolve(), tmp_path.resolve())
    assert missing == ["../../README.md#set-up"]  # no README in tmp_path: named, left as a link
    assert text == ("See bench.py, [the README](../../README.md#set-up), [search](search.md#x), "
                    "[site](https://example.org/a.md), ![img](../../img.png) and [top](#top).\n"
                    "```sh\n[kept](../../benchmarks/bench.py)\n```\nafter again\n")


def test_sphinx_roles_become_optional_cross_references():
    html = ("use :func:<code>merge</code>, :class:<code>~merger.grid.OccupancyGrid</code> and "
            ":mod:<code>merger.io</code>; <code>:not_a_role</code>")
    assert hook().sphinx_roles(html) == (
        'use <autoref identifier="merger.merge" optional><code>merge</code></autoref>, '
        '<autoref identifier="merger.grid.OccupancyGrid" optional><code>OccupancyGrid</code></autoref> and '
        '<autoref identifier="merger.io" optional><code>merger.io</code></autoref>; <code>:not_a_role</code>')


def test_the_api_reference_documents_every_public_name_of_merger():
    import merger

    pages = "\n".join(p.read_text() for p in (REPO / "docs" / "api").glob("*.md"))
    documented = set(re.findall(r"^::: merger\.(\w+)$", pages, re.M))
    public = set(merger.__all__) - {"align"}  # align: the deprecated name of search_pair
    assert public - documented == set()
    nav = yaml.safe_load((REPO / "mkdocs.yml").read_text().replace("!!python", "#"))["nav"]
    listed = re.findall(r"api/\w+\.md", str(nav))
    assert sorted(listed) == sorted(f"api/{p.name}" for p in (REPO / "docs" / "api").glob("*.md"))


def site(tmp_path, pages: dict[str, str]) -> subprocess.CompletedProcess:
    """``mkdocs build`` (strict by the config; no -q, which hides the warnings strict mode counts) of
    ``pages`` with the repository's validation and link hook."""
    pytest.importorskip("mkdocs")
    config = yaml.safe_load((REPO / "mkdocs.yml").read_text())
    (tmp_path / "docs").mkdir()
    for name, text in pages.items():
        (tmp_path / "docs" / name).write_text(text)
    own = {"site_name": "t", "docs_dir": "docs", "site_dir": str(tmp_path / "site"), "strict": True,
           "validation": config["validation"], "hooks": [str(HOOK)], "markdown_extensions": ["toc"],
           "nav": list(pages)}
    (tmp_path / "mkdocs.yml").write_text(yaml.safe_dump(own))
    return subprocess.run([sys.executable, "-m", "mkdocs", "build", "-f", str(tmp_path / "mkdocs.yml")],
                          capture_output=True, text=True, cwd=tmp_path, timeout=120)


@pytest.mark.parametrize(("link", "needle"), [
    ("[b](b.md)", None),
    ("[b](c.md)", "c.md"),  # a page that does not exist
    ("[b](b.md#no-such-heading)", "no-such-heading"),  # an anchor that does not exist
    ("[script](../no_such_script.py)", "no_such_script.py"),  # out of docs/, not in the repository
])
def test_a_strict_build_fails_on_a_broken_link(tmp_path, link, needle):
    pages = {"index.md": f"# A\n\nSee {link}.\n", "b.md": "# B\n\n## A heading\n"}
    r = site(tmp_path, pages)
    if needle is None:
        assert r.returncode == 0, r.stderr
    else:
        assert r.returncode != 0 and needle in r.stderr, r.stderr


@pytest.mark.slow
def test_the_site_builds_strictly(tmp_path):
    """The whole site, as CI builds it: every page, every link and anchor, every docstring reference."""
    pytest.importorskip("mkdocstrings")
    r = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(tmp_path / "site")],
                       capture_output=True, text=True, cwd=REPO, timeout=300)
    assert r.returncode == 0, r.stderr
    html = (tmp_path / "site" / "api" / "merger" / "index.html").read_text()
    assert 'id="merger.merge"' in html and 'id="merger.MergeResult"' in html
    # a docstring's :func:`merge` is a link to merge's entry, not text
    assert '<a class="autorefs autorefs-internal" title="merger.merge" href="#merger.merge"><code>merge</code></a>' in html


def test_one_line_numpy_entries_become_descriptions():
    """docs/hooks/docstrings.py: ``name : what it is`` (our docstrings' entries) reads as the name and its
    description, not as a type (the reference showed descriptions, unrendered, in the type column)."""
    pytest.importorskip("griffe")
    spec = importlib.util.spec_from_file_location("site_docstrings", REPO / "docs" / "hooks" / "docstrings.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    doc = ("Merge maps.\n\nA line : with a colon, not in a section.\n\nParameters\n----------\n"
           "maps : map files or :class:`~merger.grid.OccupancyGrid`\n    objects, each in its frame.\n"
           "a, b : two numbers\n**settings : any setting\n\nReturns\n-------\nMergeResult\n    the verdict.\n\n"
           "Notes\n-----\nx : stays as written in a free-text section\n")
    assert mod.one_line_entries(doc) == (
        "Merge maps.\n\nA line : with a colon, not in a section.\n\nParameters\n----------\n"
        "maps\n    map files or :class:`~merger.grid.OccupancyGrid`\n    objects, each in its frame.\n"
        "a, b\n    two numbers\n**settings\n    any setting\n\nReturns\n-------\nMergeResult\n    the verdict.\n\n"
        "Notes\n-----\nx : stays as written in a free-text section\n")
    import griffe

    parsed = griffe.Docstring(mod.one_line_entries("Parameters\n----------\nmaps : the maps, each in its frame\n"),
                              parser="numpy").parse()
    (param,) = parsed[0].value
    assert param.name == "maps" and param.description == "the maps, each in its frame" and not param.annotation
