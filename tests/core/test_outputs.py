"""The output helpers every command writes through: a file appears whole under its final name
or not at all (a signal midway included), a set of files renamed together keeps its last file
with its own companions, and the checks that refuse two outputs on one file or replacing a
file of another kind."""
from __future__ import annotations

import os

import pytest

from delta6.core import outputs
from delta6.core.errors import UserError
from delta6.core.outputs import (
    check_replaces_only,
    check_same_outputs,
    json_object,
    write_atomically,
    write_text_atomically,
    written_together,
)


def _interrupted_writer(tmp):
    tmp.write_bytes(b"half of it")
    raise KeyboardInterrupt


def test_an_interrupted_write_leaves_the_old_file_and_no_temporary(tmp_path):
    path = tmp_path / "out.json"
    with pytest.raises(KeyboardInterrupt):
        write_atomically(path, _interrupted_writer)
    assert list(tmp_path.iterdir()) == []
    path.write_text("old")
    with pytest.raises(KeyboardInterrupt):
        write_atomically(path, _interrupted_writer)
    assert list(tmp_path.iterdir()) == [path] and path.read_text() == "old"


def test_a_write_replaces_the_file_in_one_step(tmp_path):
    path = tmp_path / "out.txt"
    path.write_text("old")
    write_text_atomically(path, "new")
    assert list(tmp_path.iterdir()) == [path] and path.read_text() == "new"


def test_a_write_that_fails_is_one_line_naming_the_final_file(tmp_path):
    path = tmp_path / "gone" / "out.txt"
    with pytest.raises(UserError, match=r"cannot write .*out\.txt: "):
        write_text_atomically(path, "x")


def test_files_written_together_leave_no_last_file_without_its_companions(tmp_path,
                                                                          monkeypatch):
    onnx, js = tmp_path / "m.onnx", tmp_path / "m.json"
    onnx.write_text("old onnx")
    js.write_text("old json")
    # interrupted while writing: both old files stay, no temporary
    with pytest.raises(KeyboardInterrupt):
        with written_together(onnx, js) as (a, b):
            a.write_text("new onnx")
            raise KeyboardInterrupt
    assert (onnx.read_text(), js.read_text()) == ("old onnx", "old json")
    assert sorted(tmp_path.iterdir()) == [js, onnx]
    # interrupted between the renames: the old JSON is gone, never beside the new ONNX
    real_replace, calls = os.replace, []

    def replace(src, dst):
        calls.append(dst)
        if len(calls) == 2:
            raise KeyboardInterrupt
        real_replace(src, dst)

    monkeypatch.setattr(outputs.os, "replace", replace)
    with pytest.raises(KeyboardInterrupt):
        with written_together(onnx, js) as (a, b):
            a.write_text("new onnx")
            b.write_text("new json")
    assert calls == [onnx, js]
    assert sorted(tmp_path.iterdir()) == [onnx] and onnx.read_text() == "new onnx"
    monkeypatch.setattr(outputs.os, "replace", real_replace)
    with written_together(onnx, js) as (a, b):
        a.write_text("newer onnx")
        b.write_text("newer json")
    assert (onnx.read_text(), js.read_text()) == ("newer onnx", "newer json")
    assert sorted(tmp_path.iterdir()) == [js, onnx]


def test_two_options_on_one_file_are_refused(tmp_path):
    check_same_outputs({"--json": tmp_path / "a", "--plot": tmp_path / "b", "--x": None})
    with pytest.raises(UserError, match="--json and --plot name the same file"):
        check_same_outputs({"--json": tmp_path / "a", "--plot": tmp_path / "." / "a"})


def test_only_a_file_of_the_kind_written_is_replaced(tmp_path):
    ours, theirs = tmp_path / "ours.json", tmp_path / "theirs.json"
    ours.write_text('{"rows": []}')
    theirs.write_text('{"schema": "delta6-twin-truth/1"}')

    def is_table(path):
        return "rows" in (json_object(path) or {})

    check_replaces_only(ours, "--json", "a table", is_table)
    check_replaces_only(tmp_path / "new.json", "--json", "a table", is_table)
    with pytest.raises(UserError, match=r"theirs\.json: exists and is not a table; not replaced"):
        check_replaces_only(theirs, "--json", "a table", is_table)
    (tmp_path / "list.json").write_text("[1]")
    (tmp_path / "bin.json").write_bytes(b"\xff\x00")
    assert json_object(tmp_path / "list.json") is None
    assert json_object(tmp_path / "bin.json") is None


def test_an_output_under_a_file_says_the_file_is_no_folder(tmp_path):
    (tmp_path / "afile").write_text("x")
    with pytest.raises(UserError) as info:
        outputs.check_output_file(tmp_path / "afile" / "out.json", "--json")
    assert str(info.value).endswith("afile is a file, not a folder")
    with pytest.raises(UserError, match="does not exist"):
        outputs.check_output_file(tmp_path / "none" / "out.json", "--json")
