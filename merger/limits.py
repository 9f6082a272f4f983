"""The merger's input limits and its safe YAML reader, shared by both command lines and the bench.

The contract: what a user may hand the merger or the bench, checked at the boundary before any work —

* :data:`MAX_ROI_M`, :data:`MIN_ROI_CELLS`: the region of interest's side (a larger one is a typo or
  hours of search; a smaller one holds no structure); the search's own cap in cells is
  :data:`merger.search.MAX_ROI_CELLS`;
* :func:`read_input`: a regular file of at most a given size, read without blocking on a FIFO or a
  device (:class:`InputLimitError` otherwise);
* :func:`load_yaml`: YAML 1.2 numbers (``1e1`` is ten), parsed safely, refused before anything is built
  when its aliases would expand beyond :data:`MAX_YAML_EXPANDED` (:class:`YamlLimitError`);
* :func:`one_line`: a user's text echoed in an error message stays one line of bounded length.

``merger`` (maps, ``merger align/merge``) and ``circsim`` (scenario files, ``--set``) read their inputs
through this module, so neither depends on the other's command line. The measured cases behind each
limit are in docs/limits.md.
"""

from __future__ import annotations

import os
import re

import yaml

MAX_ROI_M = 100.0  # a larger region of interest is a typo (or hours of search), not a map
MIN_ROI_CELLS = 10  # a smaller ROI holds no structure to align (--roi 1e-9 ran on one cell)
MAX_YAML_BYTES = 1 << 20  # a map YAML or a scenario is a few kB; 1 MiB is far beyond any
MAX_YAML_EXPANDED = 2 << 20  # nodes + characters after expanding aliases (a "billion laughs" stops here)

_CONTROL = re.compile("[\x00-\x1f\x7f\x85\u2028\u2029]")


MAX_MESSAGE_CHARS = 2000  # an error message echoing a user's value is cut here


def one_line(text: str) -> str:
    """``text`` with line breaks and other control characters escaped (``\\n``): a user's file name or
    value echoed in an error message cannot break it over lines; cut after :data:`MAX_MESSAGE_CHARS`
    characters (a value of a megabyte is not echoed whole)."""
    text = str(text)
    if len(text) > MAX_MESSAGE_CHARS:
        text = f"{text[:MAX_MESSAGE_CHARS]}... ({len(text)} characters)"
    return _CONTROL.sub(lambda m: repr(m.group())[1:-1], text)


class Yaml12Loader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2 floats: ``1e1``, ``5E-2``, ``.5e3`` are numbers (YAML 1.1,
    PyYAML's default, reads an exponent without a dot as a string)."""


Yaml12Loader.yaml_implicit_resolvers = {k: list(v) for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()}
Yaml12Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"""),
    list("-+0123456789."))


class YamlLimitError(yaml.YAMLError):
    """A YAML document that would expand beyond :data:`MAX_YAML_EXPANDED` or holds a recursive alias."""


def _expanded_size(node, memo: dict, active: set) -> int:
    """Nodes plus scalar characters of ``node`` with every alias expanded (memoized per node: linear in
    the document, whatever the expansion)."""
    key = id(node)
    if key in memo:
        return memo[key]
    if key in active:
        raise YamlLimitError("a recursive alias (an anchor used inside itself)")
    if isinstance(node, yaml.ScalarNode):
        size = 1 + len(node.value)
    else:
        active.add(key)
        items = node.value if isinstance(node, yaml.SequenceNode) else [x for kv in node.value for x in kv]
        size = 1
        for child in items:
            size += _expanded_size(child, memo, active)
            if size > MAX_YAML_EXPANDED:
                break
        active.discard(key)
    memo[key] = size
    if size > MAX_YAML_EXPANDED:
        raise YamlLimitError(f"expands to more than {MAX_YAML_EXPANDED} nodes and characters (aliases "
                             "repeating anchors: a \"billion laughs\")")
    return size


def load_yaml(text: str):
    """YAML text parsed safely with YAML 1.2 floats (:class:`Yaml12Loader`); a document whose aliases
    would expand beyond :data:`MAX_YAML_EXPANDED` nodes and characters, or refer to themselves, raises
    :class:`YamlLimitError` before anything is built."""
    loader = Yaml12Loader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _expanded_size(node, {}, set())
        return loader.construct_document(node)
    finally:
        loader.dispose()


def read_input(path, limit: int, what: str = "file") -> bytes:
    """The bytes of the regular file ``path``, at most ``limit`` of them. A FIFO, a device, a socket or a
    folder is refused without blocking (opened non-blocking, checked with fstat before any read), and so
    is a larger file; OSError (missing, unreadable) passes through. ValueError messages start with the
    path (the caller adds its own context)."""
    import stat

    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            kind = ("a folder" if stat.S_ISDIR(st.st_mode) else "a FIFO (named pipe)" if stat.S_ISFIFO(st.st_mode)
                    else "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode) else "a socket"
                    if stat.S_ISSOCK(st.st_mode) else "not a regular file")
            raise InputLimitError(f"{path}: expected a regular {what}, got {kind}")
        if st.st_size > limit:
            raise InputLimitError(f"{path}: {st.st_size} bytes: expected a {what} of at most {limit} bytes")
        chunks, total = [], 0
        while True:
            b = os.read(fd, min(1 << 20, limit + 1 - total))
            if not b:
                break
            chunks.append(b)
            total += len(b)
            if total > limit:
                raise InputLimitError(f"{path}: expected a {what} of at most {limit} bytes (it grew while read)")
        return b"".join(chunks)
    finally:
        os.close(fd)


class InputLimitError(ValueError):
    """An input that is not a regular file or exceeds its size limit (message starts with the path)."""

    def __init__(self, message: str) -> None:
        super().__init__(one_line(message))
