"""merger.limits: the safe YAML reader (YAML 1.2 numbers, alias bombs refused before anything is built),
the regular-file reader (FIFOs, folders and large files refused without blocking) and one-line echoes."""

import os
import threading

import pytest
import yaml

from merger.limits import (
    MAX_MESSAGE_CHARS,
    MAX_YAML_EXPANDED,
    InputLimitError,
    YamlLimitError,
    load_yaml,
    one_line,
    read_input,
)


def test_yaml_12_numbers_where_pyyaml_reads_strings():
    assert yaml.safe_load("a: 1e1") == {"a": "1e1"}  # PyYAML's YAML 1.1: a string
    assert load_yaml("a: 1e1\nb: 5E-2\nc: .5e3\nd: -2.5e+1\ne: 0.05\nf: 7\ng: 1e") == {
        "a": 10.0, "b": 0.05, "c": 500.0, "d": -25.0, "e": 0.05, "f": 7, "g": "1e"}
    assert load_yaml("") is None


def test_an_alias_bomb_is_refused_and_a_fair_alias_is_not():
    bomb = "a: &a ['xxxxxxxxxx','xxxxxxxxxx','xxxxxxxxxx','xxxxxxxxxx','xxxxxxxxxx','xxxxxxxxxx']\n"
    for k in range(1, 12):  # 6^11 expanded nodes from 12 short lines
        bomb += f"{chr(97 + k)}: &{chr(97 + k)} [*{chr(96 + k)},*{chr(96 + k)},*{chr(96 + k)},*{chr(96 + k)},*{chr(96 + k)},*{chr(96 + k)}]\n"
    with pytest.raises(YamlLimitError, match=f"more than {MAX_YAML_EXPANDED} nodes"):
        load_yaml(bomb)
    assert load_yaml("base: &b {x: 1, y: 2}\nother: *b") == {"base": {"x": 1, "y": 2}, "other": {"x": 1, "y": 2}}
    with pytest.raises(YamlLimitError, match="recursive alias"):
        load_yaml("&a [*a]")
    with pytest.raises(yaml.YAMLError):  # no Python objects from tags: a safe loader
        load_yaml("!!python/object/apply:os.system ['true']")


def test_read_input_reads_a_regular_file_within_its_limit(tmp_path):
    p = tmp_path / "m.yaml"
    p.write_bytes(b"x" * 100)
    assert read_input(p, 100) == b"x" * 100
    with pytest.raises(InputLimitError) as e:
        read_input(p, 99, "map YAML")
    assert str(e.value) == f"{p}: 100 bytes: expected a map YAML of at most 99 bytes"
    with pytest.raises(InputLimitError, match="expected a regular file, got a folder"):
        read_input(tmp_path, 100)
    with pytest.raises(FileNotFoundError):
        read_input(tmp_path / "missing", 100)


def test_a_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    out = {}

    def read():
        try:
            read_input(fifo, 100)
        except InputLimitError as e:
            out["err"] = str(e)

    t = threading.Thread(target=read, daemon=True)
    t.start()
    t.join(10)  # no writer ever opens it: a blocking open would hang here
    assert out.get("err") == f"{fifo}: expected a regular file, got a FIFO (named pipe)"
    with pytest.raises(InputLimitError, match="a device"):
        read_input("/dev/null", 100)


def test_one_line_escapes_breaks_and_cuts_long_text():
    assert one_line("a\nb\r\x00c\u2028") == "a\\nb\\r\\x00c\\u2028"
    long = one_line("y" * (MAX_MESSAGE_CHARS + 5))
    assert long == "y" * MAX_MESSAGE_CHARS + f"... ({MAX_MESSAGE_CHARS + 5} characters)"
    assert str(InputLimitError("bad\nname")) == "bad\\nname"
