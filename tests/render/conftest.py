"""Shared fixtures of the rendering tests."""

from __future__ import annotations

import pytest

import bluesky_gym


@pytest.fixture(autouse=True)
def _headless(monkeypatch: pytest.MonkeyPatch) -> None:
    """No screen: SDL's dummy video driver (read when a window is opened)."""
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    bluesky_gym.register_envs()
