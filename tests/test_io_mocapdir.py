"""Finding the motion-capture folder (kinodyn.io.mocapdir)."""

from __future__ import annotations

from kinodyn.io import mocapdir


def test_a_named_folder_wins_and_a_missing_one_is_none(tmp_path, monkeypatch):
    monkeypatch.setenv(mocapdir.ENV, str(tmp_path / "elsewhere"))
    assert mocapdir.find(tmp_path) == tmp_path.resolve()
    assert mocapdir.find(tmp_path / "absent") is None


def test_the_environment_variable_is_used_and_never_guessed_past(tmp_path, monkeypatch):
    monkeypatch.setenv(mocapdir.ENV, str(tmp_path))
    assert mocapdir.find() == tmp_path.resolve()
    monkeypatch.setenv(mocapdir.ENV, str(tmp_path / "absent"))
    assert mocapdir.find() is None


def test_the_folder_beside_the_working_directory_is_found(tmp_path, monkeypatch):
    monkeypatch.delenv(mocapdir.ENV, raising=False)
    (tmp_path / "shared" / "mocap").mkdir(parents=True)
    (tmp_path / "work").mkdir()
    monkeypatch.chdir(tmp_path / "work")
    found = mocapdir.find()
    assert found is not None and found.parts[-2:] == ("shared", "mocap")
