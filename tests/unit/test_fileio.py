"""Atomic file output: the target is its old content or its complete new content."""

import os

import pytest

from veriloc_rt.fileio import atomic_output, atomic_write_text


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path):
    target = tmp_path / "metrics.json"
    target.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_output(target) as tmp:
            tmp.write_text("half of the new con")
            raise RuntimeError("killed mid-write")
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["metrics.json"]


def test_a_finished_write_replaces_the_file_with_the_usual_mode(tmp_path):
    target = tmp_path / "plot.png"
    target.write_text("old")
    with atomic_output(target) as tmp:
        assert tmp.suffix == ".png" and tmp.parent == tmp_path   # same folder: rename is atomic
        tmp.write_bytes(b"new")
    assert target.read_bytes() == b"new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plot.png"]
    # the mode of a file created the ordinary way (0o666 less the umask), not mkstemp's 0o600
    reference = tmp_path / "reference"
    reference.write_text("")
    atomic_write_text(tmp_path / "fresh.json", "{}")
    assert os.stat(tmp_path / "fresh.json").st_mode == os.stat(reference).st_mode


def test_atomic_files_places_every_file_index_last(tmp_path, monkeypatch):
    from veriloc_rt import fileio

    (tmp_path / "scene.xml").write_text("old xml")
    placed = []
    real_replace = os.replace

    def spy(src, dst):
        placed.append(os.path.relpath(dst, tmp_path))
        real_replace(src, dst)

    monkeypatch.setattr(fileio.os, "replace", spy)
    with fileio.atomic_files(tmp_path) as tmp:
        assert tmp.parent == tmp_path   # same file system: each rename is atomic
        (tmp / "meshes").mkdir()
        (tmp / "meshes" / "b.ply").write_bytes(b"b")
        (tmp / "meshes" / "a.ply").write_bytes(b"a")
        (tmp / "scene.xml").write_text("new xml")
        assert (tmp_path / "scene.xml").read_text() == "old xml"   # nothing placed yet
    # the meshes first, the XML that names them last; the temporary folder is gone
    assert placed == ["meshes/a.ply", "meshes/b.ply", "scene.xml"]
    assert (tmp_path / "scene.xml").read_text() == "new xml"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["meshes", "scene.xml"]


def test_atomic_files_failure_leaves_the_folder_as_it_was(tmp_path):
    from veriloc_rt.fileio import atomic_files

    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "a.ply").write_bytes(b"old")
    with pytest.raises(RuntimeError):
        with atomic_files(tmp_path) as tmp:
            (tmp / "meshes").mkdir()
            (tmp / "meshes" / "a.ply").write_bytes(b"new, compl")
            raise RuntimeError("killed mid-write")
    assert (tmp_path / "meshes" / "a.ply").read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["meshes"]


def test_a_full_disk_names_the_target_not_the_temporary(tmp_path):
    """Issue 37: 'OSError: [Errno 28] ...' named no file (write(2) names none)."""
    import errno

    from veriloc_rt.fileio import naming

    target = tmp_path / "metrics.json"
    target.write_text("old")
    with pytest.raises(OSError) as err:
        with atomic_output(target) as tmp:
            tmp.write_text("half")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    assert (err.value.errno, err.value.filename) == (errno.ENOSPC, str(target))
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["metrics.json"]
    # an error that names its own file keeps it
    with pytest.raises(FileNotFoundError) as err, naming(target):
        open(tmp_path / "missing")
    assert err.value.filename == str(tmp_path / "missing")


def test_exchange_folders_swaps_two_folders(tmp_path):
    from veriloc_rt.fileio import exchange_folders

    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    b.mkdir()
    (a / "new").write_text("1")
    (b / "old").write_text("2")
    exchange_folders(a, b)
    assert [p.name for p in a.iterdir()] == ["old"] and [p.name for p in b.iterdir()] == ["new"]
