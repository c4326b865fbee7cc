"""The files of recorded flights: damaged ones are named, a damaged cache file is cleaned again."""

from __future__ import annotations

import os

import gymnasium as gym
import pytest

import bluesky_gym
from bluesky_gym.realtraffic import cache
from bluesky_gym.realtraffic.flights import RecordedFlights

from .synthetic import traffic_collection

bluesky_gym.register_envs()


def _damaged(good: bytes) -> dict[str, bytes]:
    """Ways a file of recorded flights can be damaged: cut short, emptied, overwritten, bytes changed inside a compressed array."""
    middle = len(good) // 2
    return {
        "truncated": good[:middle],
        "empty": b"",
        "random": os.urandom(4096),
        "flipped": good[:middle] + bytes(b ^ 0xFF for b in good[middle : middle + 64]) + good[middle + 64 :],
    }


@pytest.mark.parametrize("kind", ["truncated", "empty", "random", "flipped"])
def test_a_damaged_file_is_named(tmp_path, kind) -> None:
    good = traffic_collection(n_flights=4).save(tmp_path / "good.npz").read_bytes()
    path = tmp_path / f"{kind}.npz"
    path.write_bytes(_damaged(good)[kind])
    with pytest.raises(ValueError) as info:
        RecordedFlights.load(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and "damaged" in message
    assert "allow_pickle" not in message and "\n" not in message
    # a user's own file is not rewritten: the environment names it
    with pytest.raises(ValueError, match=f"{kind}.npz: .*damaged"):
        gym.make("RealTrafficCREnv-v0", collections=(str(path),), min_traffic=1)


@pytest.mark.parametrize("kind", ["truncated", "random", "flipped"])
def test_a_damaged_cache_file_is_cleaned_again(tmp_path, monkeypatch, capsys, kind) -> None:
    from bluesky_gym.realtraffic import sources

    monkeypatch.setenv("BLUESKY_GYM_CACHE", str(tmp_path))
    path = cache.collection_path("switzerland")
    fresh = traffic_collection(n_flights=6, seed=3)
    good = traffic_collection(n_flights=4).save(path).read_bytes()
    path.write_bytes(_damaged(good)[kind])
    cleaned = []
    monkeypatch.setattr(sources, "load_sample", lambda name, **kw: cleaned.append(name) or fresh)
    flights = cache.load_collection("switzerland")
    assert cleaned == ["switzerland"] and flights.n_flights == 6
    said = capsys.readouterr().out
    assert str(path) in said and "damaged" in said and "cleaning" in said and "again" in said
    assert RecordedFlights.load(path).n_flights == 6  # rewritten
