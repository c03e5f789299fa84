"""Atomic output: complete file or old file, never a half-written one."""

import os

import pytest

from vibrospeed.io.atomic import atomic_path, atomic_write_bytes, atomic_write_text


def test_write_text_and_bytes(tmp_path):
    p = tmp_path / "a.txt"
    atomic_write_text(p, "one\r\ntwo\n")
    assert p.read_bytes() == b"one\r\ntwo\n"
    atomic_write_bytes(p, b"\x00\x01")
    assert p.read_bytes() == b"\x00\x01"
    assert os.listdir(tmp_path) == ["a.txt"]


def test_error_leaves_old_file_and_no_temp(tmp_path):
    p = tmp_path / "out.csv"
    p.write_text("old")
    with pytest.raises(RuntimeError), atomic_path(p) as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".csv"
        tmp.write_text("half")
        raise RuntimeError("writer failed")
    assert p.read_text() == "old"
    assert sorted(os.listdir(tmp_path)) == ["out.csv"]


def test_writer_that_creates_nothing_is_an_error(tmp_path):
    with pytest.raises(FileNotFoundError), atomic_path(tmp_path / "x.bin"):
        pass
    assert not (tmp_path / "x.bin").exists()


def test_a_target_that_cannot_be_replaced_is_named_not_the_temporary_file(tmp_path):
    target = tmp_path / "out.csv"
    target.mkdir()  # os.replace of a file onto a folder fails
    with pytest.raises(IsADirectoryError) as e:
        atomic_write_text(target, "x\n")
    assert e.value.filename == str(target) and ".tmp" not in str(e.value)
    assert [p.name for p in tmp_path.iterdir()] == ["out.csv"]  # no temporary file left
