"""The table of environments: one row per environment, read by every part of the package.

Registration with Gymnasium, rendering, the documentation pages, the CLI, the reference policies,
the result plots, the benchmarks and the multi-agent package all look environments up here; no
other module keeps a table keyed by environment id. A row holds everything that is one
environment's: its task, its single and vector environment classes (the environment class's
docstring is its documentation page), its render scene, its classical controller, its MVP mapping,
its KPI panels, its ``-v1`` configuration and its multi-agent form (if any). Code is named by
import path (``"module:attribute"``), resolved on first use: reading the table imports no
environment, so ``import bluesky_gym`` stays cheap and the table sits below every reader (an
environment's controller, in the training layer, is named here and looked up there). The code a
row names is the environment's folder, ``bluesky_gym.environments.<name>`` (see
:mod:`bluesky_gym.environments`).

The episode limit is the task's (:attr:`bluesky_gym.tasks.base.Task.max_episode_steps`): the
task owns the limit, the table reports it.

Adding an environment is adding its folder and a row to :data:`PAPER_ENVIRONMENTS` (its ``-v1``
row follows from the row's ``v1`` field).
"""

from __future__ import annotations

import dataclasses
import importlib
import importlib.util
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from bluesky_gym.tasks import REFERENCE_POLICIES

#: The plan view drawn for a task without a scene of its own (every aircraft around the ownship).
GENERIC_SCENE = "bluesky_gym.render.scenes.generic:generic_scene"


def resolve(path: str) -> Any:
    """Import ``"module:attribute"`` and return the attribute."""
    module, sep, attr = path.partition(":")
    if not sep or not module or not attr:
        raise ValueError(f"expected an import path 'module:attribute', got {path!r}")
    return getattr(importlib.import_module(module), attr)


@dataclass(frozen=True)
class MultiAgentEntry:
    """The multi-agent form of an environment: every aircraft is an agent.

    Attributes:
        name: PettingZoo environment name (``"sector_cr_v0"``).
        task: Batched multi-agent task class.
        parallel_env: PettingZoo ``ParallelEnv`` class.
        centralised_id: Gymnasium id of the centralised form (one agent steering every aircraft),
            or None (the ``-v1`` names have none).
        centralised_env: Its environment class.
        scene: Scene builder ``(task, env_index) -> Scene`` of the multi-agent picture.
        options: Configuration values of this name, ``(name, value)`` pairs of the task's config
            (a ``_v1`` name: float32 spaces with finite bounds and the ``-v1`` fixes the
            multi-agent form has).
        v1: The ``-v1`` fixes of the single-agent row that this multi-agent form has (its
            ``_v1`` name sets them, with float32 spaces); the others change functions of the
            single-agent step that the multi-agent task does not share (docs/multiagent.md lists
            them).
    """

    name: str
    task: str
    parallel_env: str
    centralised_id: str | None
    centralised_env: str
    scene: str
    options: tuple[tuple[str, Any], ...] = ()
    v1: tuple[tuple[str, Any], ...] = ()

    def task_class(self) -> type[Any]:
        """The batched multi-agent task class."""
        cls: type[Any] = resolve(self.task)
        return cls

    def scene_builder(self) -> Callable[[Any, int], Any]:
        """The scene builder of the multi-agent picture."""
        builder: Callable[[Any, int], Any] = resolve(self.scene)
        return builder


@dataclass(frozen=True)
class EnvEntry:
    """One environment.

    Attributes:
        id: Gymnasium id.
        task: Batched task class (owns the MDP and the episode limit).
        env: Single-environment class (Gymnasium ``entry_point``).
        vector_env: Natively batched environment class (Gymnasium ``vector_entry_point``).
        scene: Scene builder ``(task, env_index) -> Scene`` drawn by the renderer.
        multiagent: The multi-agent form, if the problem has one.
        options: Configuration values of this id, ``(name, value)`` pairs of the task's config
            (registered as the id's keyword arguments): a ``-v1`` id is its task with the
            configuration fields that fix the ``-v0`` defects set.
        data: Import path of a no-argument callable telling whether the data the default
            configuration needs is on this machine (None: the environment needs no data). The id
            is registered, listed and described either way; its first reset prepares the data.
        data_note: Import path of a no-argument callable saying, when the data are not prepared,
            where they would go and how to prepare them (None when they are).
        classical: Import path of the classical controller (a no-argument factory of a
            :class:`bluesky_gym.training.policies.Policy`), the ``classical`` reference policy;
            None: the environment has none.
        mvp: Import path of the :class:`bluesky_gym.multiagent.policies.MVPMapping` of the
            ``mvp`` reference policy; None for an environment without traffic (nothing to
            resolve). A ``-v1`` configuration with ``speed_step_in_knots`` scales its speed step.
        kpis: The panels of the environment's KPI figure, ``(episode-log column, axis label)``
            pairs (``kpis_<env>.png``); empty: every KPI that varies.
        v1: The configuration of the ``-v1`` id made from this row: the fields that fix the
            ``-v0`` defects of its task (float32 spaces with finite bounds are added;
            docs/environments-v1.md lists them with reasons); None: no ``-v1`` id.
        device_step: Import path of the class that runs the task's vector step on a CUDA device
            (constructed with the task and the environment's tensor converter; its ``supports(task)``
            says whether a configuration can); None: with ``device="cuda"`` only the physics runs
            there.
    """

    id: str
    task: str
    env: str
    vector_env: str
    scene: str = GENERIC_SCENE
    multiagent: MultiAgentEntry | None = None
    options: tuple[tuple[str, Any], ...] = ()
    data: str | None = None
    data_note: str | None = None
    classical: str | None = None
    mvp: str | None = None
    kpis: tuple[tuple[str, str], ...] = ()
    v1: tuple[tuple[str, Any], ...] | None = None
    device_step: str | None = None

    def task_class(self) -> type[Any]:
        """The batched task class."""
        cls: type[Any] = resolve(self.task)
        return cls

    def env_class(self) -> type[Any]:
        """The single-environment class."""
        cls: type[Any] = resolve(self.env)
        return cls

    def vector_env_class(self) -> type[Any]:
        """The natively batched environment class."""
        cls: type[Any] = resolve(self.vector_env)
        return cls

    def scene_builder(self) -> Callable[[Any, int], Any]:
        """The scene builder the renderer draws this environment with."""
        builder: Callable[[Any, int], Any] = resolve(self.scene)
        return builder

    @property
    def reference_policies(self) -> tuple[str, ...]:
        """The reference policies of this environment, in :data:`REFERENCE_POLICIES` order: ``random``, and ``classical``, ``mvp`` where named."""
        has = {"random": True, "classical": self.classical is not None, "mvp": self.mvp is not None}
        return tuple(name for name in REFERENCE_POLICIES if has[name])

    @property
    def max_episode_steps(self) -> int:
        """Default episode limit in decision steps (the task's, for this id's configuration)."""
        cls = self.task_class()
        return int(cls.episode_limit(cls.make_config(dict(self.options))))

    def is_available(self) -> bool:
        """Whether the modules of the environment classes are present."""
        return all(importlib.util.find_spec(p.partition(":")[0]) is not None for p in (self.task, self.env, self.vector_env))

    def data_ready(self) -> bool:
        """Whether the data of the default configuration is present (always, for an environment without data)."""
        return self.data is None or bool(resolve(self.data)())

    def data_status(self) -> str | None:
        """None when the data of the default configuration are present (or none are needed), else what to do about them."""
        if self.data_ready():
            return None
        return str(resolve(self.data_note)()) if self.data_note else "not prepared"


#: Episode-log column of the mean |altitude - target| [m] while flying (derived by the plots from the altitude reward).
ALTITUDE_ERROR = "altitude_error_m"

#: The paper's environments (``-v0``) in the order of the paper, then the recorded-traffic one and
#: the dense-traffic stress test (``DenseSectorCREnv-v0``: SectorCR with traffic entering at a rising rate).
PAPER_ENVIRONMENTS: tuple[EnvEntry, ...] = (
    EnvEntry(
        id="DescentEnv-v0",
        task="bluesky_gym.environments.descent.task:DescentTask",
        env="bluesky_gym.environments.descent.env:DescentEnv",
        vector_env="bluesky_gym.environments.descent.env:DescentVectorEnv",
        scene="bluesky_gym.environments.descent.scene:descent_scene",
        device_step="bluesky_gym.environments.descent.device_step:DescentDeviceStep",
        classical="bluesky_gym.environments.descent.controller:DescentController",
        kpis=(
            ("return", "episode return"),
            (ALTITUDE_ERROR, "mean altitude error [m]"),
            ("final_altitude", "final altitude [m] (-100: crashed)"),
            ("length", "episode length [steps]"),
        ),
        v1=(("hold_altitude_at_zero", True),),
    ),
    EnvEntry(
        id="VerticalCREnv-v0",
        task="bluesky_gym.environments.vertical_cr.task:VerticalCRTask",
        env="bluesky_gym.environments.vertical_cr.env:VerticalCREnv",
        vector_env="bluesky_gym.environments.vertical_cr.env:VerticalCRVectorEnv",
        scene="bluesky_gym.environments.vertical_cr.scene:vertical_cr_scene",
        device_step="bluesky_gym.environments.vertical_cr.device_step:VerticalCRDeviceStep",
        classical="bluesky_gym.environments.vertical_cr.controller:VerticalCRController",
        mvp="bluesky_gym.environments.vertical_cr.controller:VERTICAL_CR_MVP",
        kpis=(
            ("return", "episode return"),
            (ALTITUDE_ERROR, "mean altitude error [m]"),
            ("final_altitude", "final altitude [m] (-100: crashed)"),
            ("kpi_los_count", "losses of separation / episode"),
            ("kpi_min_separation_nm", "minimum separation [NM]"),
        ),
        v1=(("hold_altitude_at_zero", True), ("normalise_vertical_speed", True)),
    ),
    EnvEntry(
        id="PlanWaypointEnv-v0",
        task="bluesky_gym.environments.plan_waypoint.task:PlanWaypointTask",
        env="bluesky_gym.environments.plan_waypoint.env:PlanWaypointEnv",
        vector_env="bluesky_gym.environments.plan_waypoint.env:PlanWaypointVectorEnv",
        scene="bluesky_gym.environments.plan_waypoint.scene:plan_waypoint_scene",
        device_step="bluesky_gym.environments.plan_waypoint.device_step:PlanWaypointDeviceStep",
        classical="bluesky_gym.environments.plan_waypoint.controller:PlanWaypointController",
        kpis=(
            ("return", "episode return"),
            ("waypoints_completed", "waypoints completed"),
            ("kpi_track_distance_km", "track distance [km]"),
            ("length", "episode length [steps]"),
        ),
        v1=(("airborne_start", True), ("reach_same_step", True)),
    ),
    EnvEntry(
        id="HorizontalCREnv-v0",
        task="bluesky_gym.environments.horizontal_cr.task:HorizontalCRTask",
        env="bluesky_gym.environments.horizontal_cr.env:HorizontalCREnv",
        vector_env="bluesky_gym.environments.horizontal_cr.env:HorizontalCRVectorEnv",
        scene="bluesky_gym.environments.horizontal_cr.scene:horizontal_cr_scene",
        device_step="bluesky_gym.environments.horizontal_cr.device_step:HorizontalCRDeviceStep",
        multiagent=MultiAgentEntry(
            name="horizontal_cr_v0",
            task="bluesky_gym.environments.horizontal_cr.multiagent:HorizontalCRMultiAgentTask",
            parallel_env="bluesky_gym.environments.horizontal_cr.parallel:HorizontalCRParallelEnv",
            centralised_id="HorizontalCRCentralised-v0",
            centralised_env="bluesky_gym.environments.horizontal_cr.multiagent:HorizontalCRCentralisedEnv",
            scene="bluesky_gym.environments.horizontal_cr.multiagent:horizontal_cr_multiagent_scene",
            v1=(("airborne_start", True),),
        ),
        classical="bluesky_gym.environments.horizontal_cr.controller:HorizontalCRController",
        mvp="bluesky_gym.environments.horizontal_cr.controller:HORIZONTAL_CR_MVP",
        kpis=(
            ("return", "episode return"),
            ("kpi_success", "success rate"),
            ("kpi_los_count", "losses of separation / episode"),
            ("kpi_min_separation_nm", "minimum separation [NM]"),
            ("kpi_mean_abs_drift_deg", "mean |drift| [deg]"),
            ("kpi_extra_track_km", "extra track [km]"),
        ),
        v1=(("airborne_start", True),),
    ),
    EnvEntry(
        id="SectorCREnv-v0",
        task="bluesky_gym.environments.sector_cr.task:SectorCRTask",
        env="bluesky_gym.environments.sector_cr.env:SectorCREnv",
        vector_env="bluesky_gym.environments.sector_cr.env:SectorCRVectorEnv",
        scene="bluesky_gym.environments.sector_cr.scene:sector_cr_scene",
        device_step="bluesky_gym.environments.sector_cr.device_step:SectorCRDeviceStep",
        multiagent=MultiAgentEntry(
            name="sector_cr_v0",
            task="bluesky_gym.environments.sector_cr.multiagent:SectorCRMultiAgentTask",
            parallel_env="bluesky_gym.environments.sector_cr.parallel:SectorCRParallelEnv",
            centralised_id="SectorCRCentralised-v0",
            centralised_env="bluesky_gym.environments.sector_cr.multiagent:SectorCRCentralisedEnv",
            scene="bluesky_gym.environments.sector_cr.multiagent:sector_cr_multiagent_scene",
            v1=(("flight_level_altitude", True), ("speed_step_in_knots", True)),
        ),
        classical="bluesky_gym.environments.sector_cr.controller:SectorCRController",
        mvp="bluesky_gym.environments.sector_cr.controller:SECTOR_CR_MVP",
        kpis=(
            ("return", "episode return"),
            ("kpi_los_count", "losses of separation / episode"),
            ("kpi_min_separation_nm", "minimum separation [NM]"),
            ("kpi_mean_abs_drift_deg", "mean |drift| [deg]"),
            ("kpi_extra_track_km", "extra track [km]"),
        ),
        v1=(("flight_level_altitude", True), ("speed_step_in_knots", True), ("exit_ends_episode", True)),
    ),
    EnvEntry(
        id="StaticObstacleEnv-v0",
        task="bluesky_gym.environments.static_obstacle.task:StaticObstacleTask",
        env="bluesky_gym.environments.static_obstacle.env:StaticObstacleEnv",
        vector_env="bluesky_gym.environments.static_obstacle.env:StaticObstacleVectorEnv",
        scene="bluesky_gym.environments.static_obstacle.scene:static_obstacle_scene",
        device_step="bluesky_gym.environments.static_obstacle.device_step:StaticObstacleDeviceStep",
        classical="bluesky_gym.environments.static_obstacle.controller:StaticObstacleController",
        kpis=(
            ("return", "episode return"),
            ("kpi_success", "success rate"),
            ("crashed", "restricted-area entries"),
            ("kpi_mean_abs_drift_deg", "mean |drift| [deg]"),
            ("kpi_time_to_goal_s", "time to goal [s]"),
        ),
        v1=(("flight_level_altitude", True), ("speed_step_in_knots", True), ("step_reward", True), ("clear_start", True)),
    ),
    EnvEntry(
        id="MergeEnv-v0",
        task="bluesky_gym.environments.merge.task:MergeTask",
        env="bluesky_gym.environments.merge.env:MergeEnv",
        vector_env="bluesky_gym.environments.merge.env:MergeVectorEnv",
        scene="bluesky_gym.environments.merge.scene:merge_scene",
        device_step="bluesky_gym.environments.merge.device_step:MergeDeviceStep",
        multiagent=MultiAgentEntry(
            name="merge_v0",
            task="bluesky_gym.environments.merge.multiagent:MergeMultiAgentTask",
            parallel_env="bluesky_gym.environments.merge.parallel:MergeParallelEnv",
            centralised_id="MergeCentralised-v0",
            centralised_env="bluesky_gym.environments.merge.multiagent:MergeCentralisedEnv",
            scene="bluesky_gym.environments.merge.multiagent:merge_multiagent_scene",
        ),
        classical="bluesky_gym.environments.merge.controller:MergeController",
        mvp="bluesky_gym.environments.merge.controller:MERGE_MVP",
        kpis=(
            ("return", "episode return"),
            ("faf_reach", "reached the FAF"),
            ("kpi_los_count", "losses of separation / episode"),
            ("kpi_min_separation_nm", "minimum separation [NM]"),
            ("kpi_mean_abs_drift_deg", "mean |drift| [deg]"),
        ),
        v1=(("faf_same_step", True), ("faf_distance_in_nm", True), ("margins_in_km", True), ("normalise_airspeed", True)),
    ),
    EnvEntry(
        id="RealTrafficCREnv-v0",
        task="bluesky_gym.environments.real_traffic.task:RealTrafficTask",
        env="bluesky_gym.environments.real_traffic.env:RealTrafficCREnv",
        vector_env="bluesky_gym.environments.real_traffic.env:RealTrafficCRVectorEnv",
        scene="bluesky_gym.environments.real_traffic.scene:real_traffic_scene",
        data="bluesky_gym.realtraffic.cache:default_data_ready",
        data_note="bluesky_gym.realtraffic.cache:default_data_note",
        classical="bluesky_gym.environments.real_traffic.controller:RealTrafficController",
        device_step="bluesky_gym.environments.real_traffic.device_step:RealTrafficDeviceStep",
        v1=(),
    ),
    EnvEntry(
        id="DenseSectorCREnv-v0",
        task="bluesky_gym.environments.dense_sector_cr.task:DenseSectorCRTask",
        env="bluesky_gym.environments.dense_sector_cr.env:DenseSectorCREnv",
        vector_env="bluesky_gym.environments.dense_sector_cr.env:DenseSectorCRVectorEnv",
        scene="bluesky_gym.environments.dense_sector_cr.scene:dense_sector_cr_scene",
        device_step="bluesky_gym.environments.dense_sector_cr.device_step:DenseSectorCRDeviceStep",
        multiagent=MultiAgentEntry(
            name="dense_sector_cr_v0",
            task="bluesky_gym.environments.dense_sector_cr.multiagent:DenseSectorCRMultiAgentTask",
            parallel_env="bluesky_gym.environments.dense_sector_cr.parallel:DenseSectorCRParallelEnv",
            centralised_id="DenseSectorCRCentralised-v0",
            centralised_env="bluesky_gym.environments.dense_sector_cr.multiagent:DenseSectorCRCentralisedEnv",
            scene="bluesky_gym.environments.sector_cr.multiagent:sector_cr_multiagent_scene",
            v1=(("flight_level_altitude", True), ("speed_step_in_knots", True)),
        ),
        classical="bluesky_gym.environments.sector_cr.controller:SectorCRController",
        mvp="bluesky_gym.environments.sector_cr.controller:SECTOR_CR_MVP",
        kpis=(
            ("return", "episode return"),
            ("kpi_los_count", "losses of separation / episode"),
            ("kpi_los_per_flight_hour", "losses of separation / flight-hour"),
            ("kpi_time_to_first_los_s", "time to the first loss of separation [s]"),
            ("kpi_min_separation_nm", "minimum separation [NM]"),
            ("kpi_fuel_kg", "fuel burned [kg]"),
        ),
        v1=(("flight_level_altitude", True), ("speed_step_in_knots", True), ("exit_ends_episode", True)),
    ),
)


def _v1_multiagent(m: MultiAgentEntry | None) -> MultiAgentEntry | None:
    """The ``_v1`` multi-agent form of a ``_v0`` one (None without one)."""
    if m is None:
        return None
    return dataclasses.replace(m, name=m.name.replace("_v0", "_v1"), centralised_id=None, options=(("float32_spaces", True), *m.v1))


def _v1(row: EnvEntry) -> EnvEntry:
    """The ``-v1`` row of a ``-v0`` row: the same classes, scene, policies and panels, the ``-v1`` configuration."""
    assert row.v1 is not None
    return dataclasses.replace(
        row, id=row.id.replace("-v0", "-v1"), multiagent=_v1_multiagent(row.multiagent), options=(("float32_spaces", True), *row.v1), v1=None
    )


#: Every environment: the paper's seven (``-v0``), the recorded-traffic one and the dense-traffic
#: stress test, then their ``-v1`` versions.
ENVIRONMENTS: tuple[EnvEntry, ...] = (*PAPER_ENVIRONMENTS, *(_v1(row) for row in PAPER_ENVIRONMENTS if row.v1 is not None))


def env_ids() -> list[str]:
    """Ids of the environments whose modules are present, in table order."""
    return [e.id for e in ENVIRONMENTS if e.is_available()]


def entry(env_id: str) -> EnvEntry:
    """The row of ``env_id`` (``ValueError`` naming the known ids if there is none)."""
    for e in ENVIRONMENTS:
        if e.id == env_id:
            return e
    raise ValueError(f"unknown environment {env_id!r}; available: {', '.join(e.id for e in ENVIRONMENTS)}")


def multiagent_entries() -> list[MultiAgentEntry]:
    """The multi-agent forms, in table order (the ``_v0`` names, then the ``_v1`` names)."""
    return [e.multiagent for e in ENVIRONMENTS if e.multiagent is not None]


def multiagent_entry(name: str) -> MultiAgentEntry:
    """The multi-agent form named ``name`` (PettingZoo name such as ``"sector_cr_v0"``, or its centralised id)."""
    for m in multiagent_entries():
        if name in (m.name, m.centralised_id):
            return m
    raise ValueError(f"unknown multi-agent environment {name!r}; available: {', '.join(m.name for m in multiagent_entries())}")


def single_agent_entry(multiagent_name: str) -> EnvEntry:
    """The single-agent row whose multi-agent form is ``multiagent_name``."""
    for e in ENVIRONMENTS:
        if e.multiagent is not None and multiagent_name in (e.multiagent.name, e.multiagent.centralised_id):
            return e
    raise ValueError(f"unknown multi-agent environment {multiagent_name!r}")


def scene_builder(env_id: str) -> Callable[[Any, int], Any]:
    """The scene builder of ``env_id``; the generic plan view for an id without a row."""
    for e in ENVIRONMENTS:
        if e.id == env_id:
            return e.scene_builder()
    generic: Callable[[Any, int], Any] = resolve(GENERIC_SCENE)
    return generic


def device_step_class(task_class: type[Any]) -> type[Any] | None:
    """The class running the vector step of ``task_class`` on a CUDA device (its row's ``device_step``), or None."""
    for e in ENVIRONMENTS:
        if e.device_step is not None and e.task_class() is task_class:
            cls: type[Any] = resolve(e.device_step)
            return cls
    return None
