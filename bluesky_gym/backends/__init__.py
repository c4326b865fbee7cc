"""Physics backends: the native batched core, or the real BlueSky simulator."""

from __future__ import annotations

from bluesky_gym.core import Physics, Simulator

BACKENDS = ("native", "bluesky", "cuda")


def make_physics(backend: str, dt: float, n_envs: int, max_aircraft: int, max_waypoints: int) -> Physics:
    """Create a physics provider.

    Args:
        backend: ``"native"`` (the batched compiled core), ``"bluesky"`` (BlueSky 1.1.1 in-process) or
            ``"cuda"`` (the native core with its state on a CUDA GPU while it steps:
            :class:`~bluesky_gym.core.DeviceSimulator`, the ``gpu`` extra).
        dt: Simulation time step [s].
        n_envs: Number of airspaces.
        max_aircraft: Aircraft slots per airspace.
        max_waypoints: Route capacity per aircraft.
    """
    if backend == "native":
        return Simulator(n_envs, max_aircraft, dt=dt, max_waypoints=max_waypoints)
    if backend == "bluesky":
        from bluesky_gym.backends.bluesky_sim import BlueSkyPhysics

        if n_envs != 1:
            raise ValueError(
                "the 'bluesky' backend simulates one airspace per process (BlueSky has one global simulator); "
                "for several environments use gymnasium.vector.AsyncVectorEnv, one process per environment"
            )
        return BlueSkyPhysics(max_aircraft, dt=dt, max_waypoints=max_waypoints)
    if backend == "cuda":
        from bluesky_gym.core import DeviceSimulator

        return DeviceSimulator(n_envs, max_aircraft, dt=dt, max_waypoints=max_waypoints)
    raise ValueError(f"unknown backend {backend!r}; choose one of {BACKENDS}")
