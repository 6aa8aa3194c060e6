"""Shared fixtures: the real motion-capture folder (tests that need it skip cleanly without it), the
built-in clip store with its support phases, and the MuJoCo body of the built-in humanoid."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

MOCAP = Path(os.environ.get("KINODYN_MOCAP", Path(__file__).resolve().parents[1] / ".." / "shared" / "mocap")).resolve()


def mocap_files(pattern: str) -> list[Path]:
    """Files under the shared mocap folder matching ``pattern`` (empty when the folder is absent)."""
    return sorted(MOCAP.glob(pattern)) if MOCAP.is_dir() else []


@pytest.fixture
def mocap_dir() -> Path:
    if not MOCAP.is_dir():
        pytest.skip(f"shared motion-capture folder not found ({MOCAP.name} beside the repository)")
    return MOCAP


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


@pytest.fixture(scope="module")
def body():
    """The physics body (:class:`kinodyn.physics.body.CharacterBody`) of the built-in humanoid."""
    from kinodyn.data.skeleton import humanoid
    from kinodyn.physics.body import build_body

    return build_body(humanoid())


@pytest.fixture(scope="session")
def clip_store():
    """Every built-in clip in one :class:`kinodyn.clips.ClipStore`, with support phases (frozen, shared)."""
    from kinodyn.blend.library import builtin

    return builtin()
