"""Shared fixtures: the real motion-capture folder (tests that need it skip cleanly without it)."""

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
