"""Reading user files safely (veriloc_rt.inputs): each check against a file made to fail it."""

import os

import pytest

from veriloc_rt.errors import InputError, bad_value
from veriloc_rt.inputs import (MAX_JSON_DEPTH, check_out_dir, check_path, parse_json, read_bytes,
                               read_text)


def test_read_bytes_refuses_a_folder_and_a_long_file(tmp_path):
    with pytest.raises(InputError, match="is a folder"):
        read_bytes(tmp_path, "f", "file", 10)
    f = tmp_path / "big"
    f.write_bytes(b"x" * 11)
    with pytest.raises(InputError, match="11 bytes, expected at most 10"):
        read_bytes(f, "f", "file", 10)
    assert read_bytes(f, "f", "file", 11) == b"x" * 11


def test_read_text_drops_the_byte_order_mark(tmp_path):
    f = tmp_path / "t"
    f.write_bytes(b"\xef\xbb\xbfa,b\n")
    assert read_text(f, "f", "file", 100) == "a,b\n"


def test_check_path_limits():
    assert str(check_path("a/b", "f")) == "a/b"
    with pytest.raises(InputError, match="component of 256 bytes"):
        check_path("d/" + "x" * 256, "f")
    with pytest.raises(InputError, match="non-empty path"):
        check_path("", "f")


def test_parse_json_rejects_what_json_loads_lets_through():
    # a depth exactly at the limit parses; one more level is refused before the parser recurses
    assert parse_json("[" * MAX_JSON_DEPTH + "]" * MAX_JSON_DEPTH, "f") is not None
    with pytest.raises(InputError, match="nested"):
        parse_json("[" * (MAX_JSON_DEPTH + 1) + "]" * (MAX_JSON_DEPTH + 1), "f")
    with pytest.raises(InputError, match="NaN is not a JSON number"):
        parse_json('{"a": NaN}', "f")
    with pytest.raises(InputError, match="duplicate key 'a'"):
        parse_json('{"b": {"a": 1, "a": 2}}', "f")
    # brackets inside strings are not nesting
    assert parse_json('{"a": "' + "[" * 100 + '"}', "f") == {"a": "[" * 100}


def test_check_out_dir_leaves_nothing_behind(tmp_path):
    assert check_out_dir(tmp_path / "new" / "deeper", "--out") == tmp_path / "new" / "deeper"
    assert os.listdir(tmp_path) == []  # not even the folder: the run creates it


def test_messages_stay_short_and_on_one_line():
    msg = str(bad_value("x", "y" * 10_000, "z"))
    assert len(msg) < 200
    assert "digits" in str(bad_value("x", 10**5000, "z"))
    assert "\n" not in str(InputError("a\nb", "c\r\nd"))


def test_check_out_dir_names_a_symbolic_link_loop_and_a_dangling_link(tmp_path):
    """Issue 37: a loop given as --out was called 'dangling'."""
    a, b = tmp_path / "a", tmp_path / "b"
    a.symlink_to(b)
    b.symlink_to(a)
    for out in (a, a / "sub"):
        with pytest.raises(InputError) as err:
            check_out_dir(out, "--out")
        assert str(err.value) == f"--out: '{a}' is a symbolic link loop"
    gone = tmp_path / "gone"
    gone.symlink_to(tmp_path / "nowhere" / "x")
    with pytest.raises(InputError) as err:
        check_out_dir(gone, "--out")
    assert str(err.value) == f"--out: '{gone}' is a dangling symbolic link"
