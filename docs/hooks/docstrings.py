"""A Griffe extension for the API reference (mkdocs.yml, mkdocstrings' ``extensions``): our docstrings'
one-line numpy entries read as their descriptions.

The code's docstrings write a parameter (or attribute, or returned value) on one line, ``name : what it
is``, with more lines indented below it. Numpy style reads the text after `` : `` as the *type*, so the
reference showed every description in the type column (unrendered: its Sphinx roles and code spans as
raw text) and an empty description. :func:`one_line_entries` rewrites such an entry as ``name`` with the
text as the first line of its description, before Griffe parses the docstring; the source is untouched.
"""

from __future__ import annotations

import re

import griffe

SECTIONS = {"Parameters", "Other Parameters", "Attributes", "Returns", "Yields", "Receives", "Raises",
            "Warns", "Keyword Arguments"}
RULE = re.compile(r"^-{3,}\s*$")
# a name (or several, comma-separated; ``*args``/``**kwargs``) at the section's indentation, then " : "
ENTRY = re.compile(r"^(\*{0,2}[A-Za-z_]\w*(?:\s*,\s*\*{0,2}[A-Za-z_]\w*)*)\s+:\s+(\S.*)$")


def one_line_entries(text: str) -> str:
    """``name : description`` entries of a numpy docstring's sections → ``name`` and an indented
    description line (continuation lines are already indented below the entry)."""
    lines = text.split("\n")
    out: list[str] = []
    section = False
    for k, line in enumerate(lines):
        if k + 1 < len(lines) and RULE.match(lines[k + 1]) and line.strip() and not line.startswith(" "):
            section = line.strip() in SECTIONS
            out.append(line)
            continue
        m = ENTRY.match(line) if section else None
        if m:
            out.extend([m.group(1), "    " + m.group(2)])
        else:
            out.append(line)
    return "\n".join(out)


class OneLineEntries(griffe.Extension):
    """Rewrites every object's docstring with :func:`one_line_entries` as Griffe loads it."""

    def on_instance(self, *, obj: griffe.Object, **kwargs) -> None:  # noqa: ARG002 (Griffe's signature)
        if obj.docstring is not None:
            obj.docstring.value = one_line_entries(obj.docstring.value)
