"""Blend scripts of real motion capture (CMU), for the evaluation of :mod:`kinodyn.blend.evaluate`.

The motion-capture files are not part of kinodyn; each function takes the folder that holds them (the
layout of the CMU collection described in its manifest: ``locomotion/``, ``reactions/``, ``fighting/``)
and returns a :class:`~kinodyn.blend.script.Script`, or ``None`` when a file is missing. The cgspeed
BVH conversions start with a T-pose frame that is not capture: it is dropped (``drop_first: 1``).

- :func:`fig12_script`: the paper's figures 12 and 13 (walk, run, faster walk, a fighting move, walk,
  jump) with clips of four CMU subjects (ASF/AMC);
- :func:`walk_run_walk`: a walk, a run and the walk again (ASF/AMC);
- :func:`walk_stumble`: a walk into a stumble (CMU 104_13) and back to the walk (BVH);
- :func:`walk_fall_getup`: a walk into a fall on the face (90_16), a get-up (140_01), then standing (BVH).

Each script starts from and ends in a standing pose, its neutral pose: a frame of subject 01 standing
before the first jump of 01_01 (ASF/AMC scripts) or of subject 90 standing before the fall of 90_16
(BVH scripts), feet side by side (without one, the mixer would stand in the first clip's first double
support, a walking stride).
"""

from __future__ import annotations

from pathlib import Path

from kinodyn.io import mocapdir

__all__ = ["default_folder", "fig12_script", "scripts", "walk_fall_getup", "walk_run_walk", "walk_stumble"]


def default_folder() -> Path | None:
    """The motion-capture folder (:func:`kinodyn.io.mocapdir.find`: ``$KINODYN_MOCAP``, else
    ``shared/mocap`` beside the checkout), or None when there is none."""
    return mocapdir.find()


def _have(folder: Path | None, *files) -> bool:
    return folder is not None and all((Path(folder) / f).is_file() for f in files)


def _amc_loco(folder: Path) -> dict:
    loco = Path(folder) / "locomotion"
    return {
        "walk": {"file": str(loco / "cmu_07_05-walk.amc"), "fps": 60, "start": 0.3167, "stop": 1.9167, "cyclic": True},
        "run": {"file": str(loco / "cmu_09_06-run.amc"), "fps": 60, "start": 0.2833, "stop": 1.0167, "cyclic": True},
        # the neutral pose: subject 01 standing, feet side by side, before the first jump of 01_01
        "stand": {"file": str(loco / "cmu_01_01.amc"), "fps": 60, "start": 0.3, "stop": 0.5},
    }


def fig12_script(folder, fight=("cmu_135_06-martialArts.amc", 8.9, 11.1)):
    """Figures 12/13 with CMU clips: one cycle of a slow walk (07_05) and of a run (09_06), a fighting
    move (default: a karate kata stretch that steps into a stance and blocks, subject 135), a forward
    jump (01_01)."""
    from kinodyn.blend.script import parse_script

    name, a, b = fight
    if not _have(folder, "locomotion/cmu_07_05-walk.amc", "locomotion/cmu_09_06-run.amc",
                 "locomotion/cmu_01_01.amc", f"fighting/{name}"):
        return None
    folder = Path(folder)
    clips = _amc_loco(folder)
    clips["fight"] = {"file": str(folder / "fighting" / name), "fps": 60, "start": a, "stop": b}
    clips["jump"] = {"file": str(folder / "locomotion" / "cmu_01_01.amc"), "fps": 60, "start": 1.0, "stop": 3.2}
    return parse_script({
        "name": "cmu_fig12", "fps": 60, "ramp_in": 0.5, "ramp_out": 0.5, "clips": clips, "neutral": "stand",
        "actions": [
            {"clip": "walk", "start": 0.0, "stop": 3.0, "priority": 1},
            {"clip": "run", "start": 2.8, "stop": 6.0, "priority": 1},
            {"clip": "walk", "start": 5.8, "stop": 8.5, "priority": 1, "speed": 1.3, "key": "fast_walk"},
            {"clip": "fight", "start": 8.2, "priority": 2},
            {"clip": "walk", "start": 9.6, "stop": 12.0, "priority": 1, "key": "walk_again"},
            {"clip": "jump", "start": 11.8, "priority": 2}]})


def walk_run_walk(folder, neutral: str | None = "stand"):
    """A CMU walk cycle (07_05), a run cycle (09_06), the walk again, from and back to standing (01_01);
    ``neutral=None``: from and to the walk's first double support instead (no standing start or stop)."""
    from kinodyn.blend.script import parse_script

    if not _have(folder, "locomotion/cmu_07_05-walk.amc", "locomotion/cmu_09_06-run.amc", "locomotion/cmu_01_01.amc"):
        return None
    return parse_script({
        "name": "cmu_walk_run_walk", "fps": 60, "ramp_in": 0.5, "ramp_out": 0.5, "clips": _amc_loco(Path(folder)),
        "neutral": neutral,
        "actions": [
            {"clip": "walk", "start": 0.0, "stop": 3.0, "priority": 1},
            {"clip": "run", "start": 2.8, "stop": 6.0, "priority": 1},
            {"clip": "walk", "start": 5.8, "stop": 9.0, "priority": 1, "key": "walk_again"}]})


def _bvh_clip(folder: Path, rel: str, start: float, stop: float, **extra) -> dict:
    """A clip of the cgspeed BVH file ``rel`` under ``folder`` (its added T-pose frame dropped), at 60 fps."""
    return {"file": str(Path(folder) / rel), "drop_first": 1, "fps": 60, "start": start, "stop": stop, **extra}


def _bvh_stand(folder: Path) -> dict:
    # the neutral pose: subject 90 standing, feet side by side, before the fall of 90_16
    return _bvh_clip(folder, "reactions/cmu_90_16.bvh", 0.3, 0.5)


def _bvh_walk(folder: Path) -> dict:
    # one cycle of CMU 02_01 (left heel strike to left heel strike), after the T-pose frame
    return _bvh_clip(folder, "locomotion/cmu_02_01.bvh", 0.1, 1.2167, cyclic=True)


def _bvh_script(folder: Path, name: str, clips: dict, actions: list):
    """A script of BVH clips beside the walk (02_01) and the standing neutral pose (90_16)."""
    from kinodyn.blend.script import parse_script

    return parse_script({
        "name": name, "fps": 60, "ramp_in": 0.5, "ramp_out": 0.5, "neutral": "stand",
        "clips": {"stand": _bvh_stand(folder), "walk": _bvh_walk(folder), **clips}, "actions": actions})


def walk_stumble(folder):
    """A walk (CMU 02_01) into the stumbling walk of CMU 104_13 (from 2 s, the stumble at 3.5 s), then the
    walk again."""
    if not _have(folder, "locomotion/cmu_02_01.bvh", "reactions/cmu_104_13.bvh", "reactions/cmu_90_16.bvh"):
        return None
    clips = {"stumble": _bvh_clip(folder, "reactions/cmu_104_13.bvh", 2.0, 4.5)}
    return _bvh_script(folder, "cmu_walk_stumble", clips, [
        {"clip": "walk", "start": 0.0, "stop": 3.0, "priority": 1},
        {"clip": "stumble", "start": 2.6, "priority": 2},
        {"clip": "walk", "start": 4.6, "stop": 7.5, "priority": 1, "key": "walk_again"}])


def walk_fall_getup(folder):
    """A walk (CMU 02_01) into a fall on the face (90_16, from 2.2 s), a get-up from lying face down
    (140_01, from 1.5 s), then the standing neutral pose."""
    if not _have(folder, "locomotion/cmu_02_01.bvh", "reactions/cmu_90_16.bvh", "reactions/cmu_140_01.bvh"):
        return None
    clips = {"fall": _bvh_clip(folder, "reactions/cmu_90_16.bvh", 2.2, 4.6),
             "getup": _bvh_clip(folder, "reactions/cmu_140_01.bvh", 1.5, 6.9)}
    return _bvh_script(folder, "cmu_walk_fall_getup", clips, [
        {"clip": "walk", "start": 0.0, "stop": 2.8, "priority": 1},
        {"clip": "fall", "start": 2.6, "priority": 2},
        {"clip": "getup", "start": 4.6, "priority": 3}])


def scripts(folder=None) -> dict:
    """``{name: Script}`` of every real-clip script whose files are in ``folder`` (default
    :func:`default_folder`)."""
    folder = Path(folder) if folder is not None else default_folder()
    if folder is None or not folder.is_dir():
        return {}
    out = {}
    for f in (fig12_script, walk_run_walk, walk_stumble, walk_fall_getup):
        s = f(folder)
        if s is not None:
            out[s.name] = s
    return out
