"""Kinematic playback: clips sampled at the physics rate for a character (kinodyn.physics.playback)."""

from __future__ import annotations

import numpy as np

from kinodyn.data import library
from kinodyn.data.skeleton import humanoid
from kinodyn.physics import playback
from kinodyn.physics.world import World, WorldConfig


def test_sampled_clips_are_kept_by_content_and_handed_out_as_copies():
    """A clip sampled again (same content, another Motion object) gives the same arrays without sampling it
    again, and what a caller does to its copy does not reach the next caller."""
    from kinodyn.physics import build_body

    w = World(WorldConfig(fps=60.0))
    char = w.add_character(build_body(humanoid()), name="a")
    walk = library.load("walk")
    first = playback.sample_clip(char, walk, w.dt, None, True, False)
    again_motion = walk.replace(name="another object, same content")
    calls = []
    original = playback._sample_clip
    playback._sample_clip = lambda *a: calls.append(a) or original(*a)
    try:
        second = playback.sample_clip(char, again_motion, w.dt, None, True, False)
        other = playback.sample_clip(char, walk[:-5], w.dt, None, True, False)
    finally:
        playback._sample_clip = original
    assert len(calls) == 1, "only the clip with other content is sampled again"
    for a, b in zip(first[:3], second[:3]):
        np.testing.assert_array_equal(a, b)
        assert a is not b
    assert len(other[0]) < len(first[0])
    first[2][:] = 0.0
    third = playback.sample_clip(char, walk, w.dt, None, True, False)
    np.testing.assert_array_equal(third[0], second[0])
    assert np.abs(third[2]).max() > 0
