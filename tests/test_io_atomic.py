"""Atomic output: every writer's data reaches the disk before the rename, the process umask is never
changed, errors name the user's path, and a failed write leaves the old file."""

from __future__ import annotations

import os
import threading

import numpy as np
import pytest

from kinodyn.data import library
from kinodyn.io import atomic, save
from kinodyn.io.atomic import atomic_path, atomic_write_bytes


@pytest.fixture
def syscalls(monkeypatch):
    """Records ``("fsync", path)`` and ``("replace", src)`` in the order they happen."""
    log = []
    real_fsync, real_replace = os.fsync, os.replace

    def fsync(fd):
        log.append(("fsync", os.readlink(f"/proc/self/fd/{fd}")))
        return real_fsync(fd)

    def replace(src, dst):
        log.append(("replace", str(src)))
        return real_replace(src, dst)

    monkeypatch.setattr(os, "fsync", fsync)
    monkeypatch.setattr(os, "replace", replace)
    return log


def _synced_before_rename(log) -> bool:
    renames = [i for i, (kind, _) in enumerate(log) if kind == "replace"]
    return bool(renames) and all(("fsync", log[i][1]) in log[:i] for i in renames)


@pytest.mark.parametrize("ext", [".npz", ".bvh"])
def test_motion_files_are_synced_before_the_rename(tmp_path, syscalls, ext):
    save(tmp_path / f"walk{ext}", library.load("walk"))
    assert _synced_before_rename(syscalls), syscalls


def test_a_writer_that_does_not_sync_is_synced(tmp_path, syscalls):
    """What numpy, matplotlib and ffmpeg write into the temporary path is flushed by atomic_path."""
    with atomic_path(tmp_path / "a.npz", suffix=".npz") as tmp:
        np.savez_compressed(tmp, x=np.arange(3))
    assert _synced_before_rename(syscalls), syscalls
    assert np.load(tmp_path / "a.npz")["x"].tolist() == [0, 1, 2]


def test_plots_are_synced(tmp_path, syscalls):
    pytest.importorskip("matplotlib")
    from matplotlib.figure import Figure

    fig = Figure()
    fig.add_subplot().plot([0, 1], [1, 0])
    with atomic_path(tmp_path / "f.png", suffix=".png") as tmp:
        fig.savefig(tmp)
    assert _synced_before_rename(syscalls), syscalls


def test_the_umask_is_never_changed(tmp_path, monkeypatch):
    """Setting the umask to read it would change it for every thread of the process."""
    def no_umask(mask):
        raise AssertionError("os.umask called")

    old = os.umask(0o027)
    try:
        monkeypatch.setattr(os, "umask", no_umask)
        atomic_write_bytes(tmp_path / "x.txt", b"x")
        assert os.stat(tmp_path / "x.txt").st_mode & 0o777 == 0o640
    finally:
        monkeypatch.undo()
        os.umask(old)


def test_files_get_the_mode_of_a_plain_open_while_threads_create_files(tmp_path):
    """Files written from many threads at once all get 0666 less the umask, and the umask stays."""
    old = os.umask(0o022)
    try:
        errors = []

        def work(k):
            try:
                for i in range(20):
                    atomic_write_bytes(tmp_path / f"t{k}_{i}.bin", b"data")
                    with open(tmp_path / f"plain{k}_{i}", "wb"):
                        pass
            except Exception as e:  # noqa: BLE001 - reported below
                errors.append(e)

        threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert not errors
        modes = {os.stat(p).st_mode & 0o777 for p in tmp_path.iterdir()}
        assert modes == {0o644}
        assert os.umask(0o022) == 0o022
    finally:
        os.umask(old)


def test_umask_without_proc(monkeypatch):
    """Where /proc is missing the umask is found from a probe file, still without os.umask."""
    real_open = open

    def no_proc(path, *a, **k):
        if str(path).startswith("/proc/"):
            raise FileNotFoundError(2, "No such file or directory", str(path))
        return real_open(path, *a, **k)

    old = os.umask(0o077)
    try:
        monkeypatch.setattr("builtins.open", no_proc)
        assert atomic._current_umask() == 0o077
    finally:
        os.umask(old)


def test_a_failed_write_keeps_the_old_file_and_no_temporary(tmp_path):
    target = tmp_path / "r.bin"
    target.write_bytes(b"old")
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_bytes(b"half")
        raise RuntimeError("writer failed")
    assert target.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.bin"]


def test_errors_name_the_users_path_not_the_temporary_file(tmp_path):
    target = tmp_path / "r.bin"
    with pytest.raises(PermissionError) as ei, atomic_path(target) as tmp:
        raise PermissionError(13, "Permission denied", str(tmp))
    assert ei.value.filename == str(target)
    with pytest.raises(PermissionError) as ei:
        atomic_write_bytes("/sys/r.bin", b"x")  # refused even to root
    assert ei.value.filename == "/sys/r.bin"


def test_a_file_in_the_way_of_the_folder(tmp_path):
    (tmp_path / "a").write_text("file")
    with pytest.raises(NotADirectoryError) as ei:
        atomic_write_bytes(tmp_path / "a" / "b" / "c.bin", b"x")
    assert ei.value.filename == str(tmp_path / "a" / "b" / "c.bin")
    assert f"'{tmp_path / 'a'}' is a file" in ei.value.strerror
