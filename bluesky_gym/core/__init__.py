"""Batched simulation core reproducing BlueSky 1.1.1 (no Gymnasium, PettingZoo or pygame).

The names below are imported on first use: the package's light modules (``extras``, ``units``)
can be imported without the compiled physics.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from bluesky_gym.core.physics import Physics
    from bluesky_gym.core.simulator import DeviceSimulator, Simulator
    from bluesky_gym.core.wind import WindField

__all__ = ["DeviceSimulator", "Physics", "Simulator", "WindField"]

_MODULES = {"DeviceSimulator": "simulator", "Physics": "physics", "Simulator": "simulator", "WindField": "wind"}


def __getattr__(name: str) -> Any:
    if name in _MODULES:
        return getattr(importlib.import_module(f"bluesky_gym.core.{_MODULES[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
