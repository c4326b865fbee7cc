"""Rendering: rgb_array frames and the window for every environment, pictures, videos, CLI."""

from __future__ import annotations

import re
import sys

import gymnasium as gym
import numpy as np
import pytest

from bluesky_gym.core.extras import install_hint
from bluesky_gym.registration import available_envs

pygame = pytest.importorskip("pygame")

from bluesky_gym.render import make_renderer, palette, write_video  # noqa: E402

IDS = available_envs()


def _act(env: gym.Env, rng: np.random.Generator) -> np.ndarray:
    space = env.action_space
    return rng.uniform(space.low, space.high, space.shape)


def _check_frame(frame: object, min_colors: int = 50) -> np.ndarray:
    assert isinstance(frame, np.ndarray)
    assert frame.ndim == 3 and frame.shape[2] == 3
    assert frame.dtype == np.uint8
    assert frame.shape[0] >= 200 and frame.shape[1] >= 200
    packed = (frame[..., 0].astype(np.int32) << 16) | (frame[..., 1].astype(np.int32) << 8) | frame[..., 2]
    colors = np.unique(packed).size
    assert colors >= min_colors, f"frame looks blank: only {colors} distinct colours"
    return frame


def _count_color(frame: np.ndarray, color: tuple[int, int, int], tol: int = 12) -> int:
    return int(np.all(np.abs(frame.astype(int) - np.array(color)) <= tol, axis=-1).sum())


def _snapshot(obj: object) -> dict[str, np.ndarray]:
    return {k: v.copy() for k, v in vars(obj).items() if isinstance(v, np.ndarray)}


def _same(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> bool:
    return a.keys() == b.keys() and all(np.array_equal(a[k], b[k], equal_nan=True) for k in a)


# --- frames of every environment ---------------------------------------------------------------
@pytest.mark.parametrize("env_id", IDS)
def test_rgb_array_single_env(env_id: str) -> None:
    env = gym.make(env_id, render_mode="rgb_array")
    with pytest.raises(RuntimeError, match="before reset"):  # no state to draw yet
        env.unwrapped.render()
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    first = _check_frame(env.render())
    assert np.array_equal(first, env.render()), "drawing the same state twice must give the same frame"
    frames = [first]
    for _ in range(3):
        _, _, te, tr, _ = env.step(_act(env, rng))
        frames.append(_check_frame(env.render()))
        if te or tr:
            break
    for a, b in zip(frames[:-1], frames[1:]):
        assert a.shape == b.shape
        assert np.any(a != b), "the picture must change between steps"
    env.close()


@pytest.mark.parametrize("env_id", IDS)
def test_rendering_does_not_change_the_simulation(env_id: str) -> None:
    drawn = gym.make(env_id, render_mode="rgb_array")
    plain = gym.make(env_id)
    rng_a, rng_b = np.random.default_rng(1), np.random.default_rng(1)
    obs_a, _ = drawn.reset(seed=5)
    obs_b, _ = plain.reset(seed=5)
    for _ in range(4):
        task = drawn.unwrapped.task
        before_sim, before_task = _snapshot(task.sim), _snapshot(task)
        drawn.render()
        assert _same(before_sim, _snapshot(task.sim)), "render() changed the simulator state"
        assert _same(before_task, _snapshot(task)), "render() changed the task state"
        obs_a, r_a, te_a, tr_a, _ = drawn.step(_act(drawn, rng_a))
        obs_b, r_b, te_b, tr_b, _ = plain.step(_act(plain, rng_b))
        assert r_a == r_b and te_a == te_b and tr_a == tr_b
        assert all(np.array_equal(obs_a[k], obs_b[k]) for k in obs_a)
        if te_a or tr_a:
            break
    drawn.close()
    plain.close()


@pytest.mark.parametrize("env_id", IDS)
def test_batched_env_frame_and_grid(env_id: str) -> None:
    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point", render_mode="rgb_array", render_env=1)
    venv.reset(seed=2)
    one = _check_frame(venv.render())
    rng = np.random.default_rng(0)
    venv.step(rng.uniform(-1, 1, venv.action_space.shape))
    assert np.any(one != _check_frame(venv.render()))
    venv.close()

    grid = gym.make_vec(env_id, num_envs=4, vectorization_mode="vector_entry_point", render_mode="rgb_array", render_grid=3)
    grid.reset(seed=2)
    tiled = _check_frame(grid.render())
    assert tiled.shape[1] > one.shape[1], "a grid of 3 episodes is wider than one frame"
    assert tiled.shape[0] % 2 == 0 and tiled.shape[1] % 2 == 0
    grid.step(rng.uniform(-1, 1, grid.action_space.shape))
    assert np.any(tiled != _check_frame(grid.render()))
    # The episodes of the grid differ (seeds s, s + 1, s + 2): their tiles differ.
    renderer = grid.unwrapped._renderer
    from bluesky_gym.render.renderer import surface_to_array

    t0 = surface_to_array(renderer.draw_frame(0))
    t1 = surface_to_array(renderer.draw_frame(1))
    assert np.any(t0 != t1)
    with pytest.raises(ValueError):
        renderer.render_grid(5)
    grid.close()


# --- conflicts are visible ---------------------------------------------------------------------
def _make_conflict(task: object) -> bool:
    """Put a conflict into episode 0 through the simulator arrays; False if the task has none."""
    sim = task.sim
    others = np.flatnonzero(sim.active[0, 1:]) + 1
    if others.size:
        s = int(others[0])
        for name in ("lat", "lon", "alt"):
            getattr(sim, name)[0, s] = getattr(sim, name)[0, 0] + (0.01 if name == "lat" else 0.0)
        return bool(task.ownship_separation()[1][0].any())
    if hasattr(task, "obstacle_lat") and hasattr(task, "inside_obstacles"):
        k = int(np.argmax(task.obstacle_nv[0]))
        nv = int(task.obstacle_nv[0, k])
        sim.lat[0, 0] = task.obstacle_lat[0, k, :nv].mean()
        sim.lon[0, 0] = task.obstacle_lon[0, k, :nv].mean()
        return bool(task.inside_obstacles()[0].any())
    return False


#: Environments with traffic or restricted areas (Descent and PlanWaypoint, in every version, fly alone).
CONFLICT_IDS = [i for i in IDS if i.rsplit("-v", 1)[0] not in ("DescentEnv", "PlanWaypointEnv")]


@pytest.mark.parametrize("env_id", CONFLICT_IDS)
def test_loss_of_separation_changes_the_picture(env_id: str) -> None:
    env = gym.make(env_id, render_mode="rgb_array")
    env.reset(seed=11)
    task = env.unwrapped.task
    assert not task.ownship_separation()[1][0].any(), "the scenario of seed 11 must start without a loss of separation"
    calm = _check_frame(env.render())
    assert _make_conflict(task), f"no conflict could be constructed in {env_id}"
    alarm = _check_frame(env.render())
    red_before, red_after = _count_color(calm, palette.LOS), _count_color(alarm, palette.LOS)
    assert red_after > red_before + 100, f"loss of separation not shown in red ({red_before} -> {red_after} pixels)"
    env.close()


# --- geometry of the pictures ------------------------------------------------------------------
def test_map_is_north_up_east_right_with_a_true_scale_bar() -> None:
    from bluesky_gym.render.renderer import draw_map
    from bluesky_gym.render.scene import Fix, MapAircraft, MapScene
    from bluesky_gym.render.views import MapView

    size = 600
    view = MapView.fit(52.0, 4.0, 50.0, (0, 0, size, size))  # 100 NM across 600 px: 6 px/NM
    assert view.px_per_nm == pytest.approx(6.0)
    north = view.latlon_of_nm(0.0, 20.0)
    east = view.latlon_of_nm(20.0, 0.0)
    scene = MapScene(
        52.0,
        4.0,
        50.0,
        aircraft=[MapAircraft(0, 52.0, 4.0, hdg=90.0, trk=90.0, gs=200.0, alt=0.0, callsign="", role="own")],
        fixes=[Fix(*north, kind="ring", capture_nm=1.0), Fix(*east, kind="waypoint")],
        follow=None,
    )
    surf = pygame.Surface((size, size))
    draw_map(surf, view, scene, {})
    from bluesky_gym.render.renderer import surface_to_array

    img = surface_to_array(surf)
    c = size // 2
    own = np.array(palette.OWNSHIP)
    # Heading 90 (east): the 2-minute speed vector (200 m/s: 13 NM, 78 px) points right.
    right = img[c - 2 : c + 3, c + 30 : c + 70].reshape(-1, 3)
    left = img[c - 2 : c + 3, c - 70 : c - 30].reshape(-1, 3)
    assert np.any(np.all(np.abs(right.astype(int) - own) < 40, axis=1))
    assert not np.any(np.all(np.abs(left.astype(int) - own) < 40, axis=1))
    # North is up: the ring of the fix 20 NM north is centred 120 px above the centre.
    ring_top = img[c - 120 - 6 - 2 : c - 120 - 6 + 3, c - 2 : c + 3]
    assert _count_color(ring_top, palette.GOAL, tol=70) > 0
    # East is right: the waypoint 20 NM east is drawn 120 px right of the centre.
    assert _count_color(img[c - 8 : c + 8, c + 120 - 8 : c + 120 + 8], palette.GOAL, tol=40) > 5
    assert _count_color(img[c - 8 : c + 8, c - 120 - 8 : c - 120 + 8], palette.GOAL, tol=40) == 0
    # Scale bar: a 2-px line of TEXT colour whose length is its label's NM at 6 px/NM.
    from bluesky_gym.render.views import scale_bar_nm

    nm = scale_bar_nm(0.28 * size / view.px_per_nm)
    row = size - 22
    bar = np.flatnonzero(np.all(np.abs(img[row].astype(int) - np.array(palette.TEXT)) < 30, axis=1))
    assert bar.size > 0
    assert bar.max() - bar.min() == pytest.approx(nm * view.px_per_nm, abs=2)


def test_map_distances_match_the_simulator() -> None:
    from bluesky_gym.core import geo
    from bluesky_gym.render.views import MapView

    view = MapView.fit(52.0, 4.0, 80.0, (0, 0, 608, 608))
    lat2, lon2 = 52.5, 4.9
    x0, y0 = view.point(52.0, 4.0)
    x1, y1 = view.point(lat2, lon2)
    assert x1 > x0 and y1 < y0  # north-east is up and right
    d_px = np.hypot(x1 - x0, y1 - y0)
    d_nm = float(geo.kwikdist(52.0, 4.0, lat2, lon2))
    assert d_px / view.px_per_nm == pytest.approx(d_nm, rel=0.01)


def test_side_view_runway_right_altitude_up() -> None:
    from bluesky_gym.render.views import SideView

    view = SideView(205.0, -10.0, 5000.0, (50, 10, 500, 400))
    assert view.point(200.0, 0.0)[0] < view.point(0.0, 0.0)[0]
    assert view.point(100.0, 3000.0)[1] < view.point(100.0, 1000.0)[1]
    assert view.point(0.0, 0.0)[1] == pytest.approx(410.0)


def test_trails_grow_and_clear_on_a_new_episode() -> None:
    env_id = "HorizontalCREnv-v0" if "HorizontalCREnv-v0" in IDS else IDS[0]
    env = gym.make(env_id, render_mode="rgb_array")
    env.reset(seed=0)
    env.render()
    rng = np.random.default_rng(0)
    for _ in range(4):
        env.step(_act(env, rng))
        env.render()
    renderer = env.unwrapped._renderer
    assert len(renderer._memory[0].trails[0]) >= 2
    env.reset(seed=1)
    env.render()
    assert len(renderer._memory[0].trails[0]) == 1
    env.close()


# --- the window ---------------------------------------------------------------------------------
@pytest.mark.parametrize("env_id", IDS[:1] + [i for i in IDS if i == "HorizontalCREnv-v0"])
def test_human_window_close_and_recreate(env_id: str) -> None:
    env = gym.make(env_id, render_mode="human")
    env.reset(seed=0)  # human mode draws at reset
    surface = pygame.display.get_surface()
    assert surface is not None and surface.get_size()[0] > 200
    assert env.render() is None
    rng = np.random.default_rng(0)
    env.step(_act(env, rng))
    assert pygame.display.get_surface() is not None
    # The user closes the window: it goes away, the environment keeps running without it.
    pygame.event.post(pygame.event.Event(pygame.QUIT))
    env.step(_act(env, rng))
    assert not pygame.display.get_init() or pygame.display.get_surface() is None
    env.step(_act(env, rng))
    assert not pygame.display.get_init() or pygame.display.get_surface() is None
    env.close()
    # A new environment (or the same one after close) opens a new window in the same process.
    env = gym.make(env_id, render_mode="human")
    env.reset(seed=1)
    assert pygame.display.get_surface() is not None
    env.close()
    assert not pygame.display.get_init() or pygame.display.get_surface() is None
    env.reset(seed=2)
    env.render()
    assert pygame.display.get_surface() is not None
    env.close()


def test_human_window_batched() -> None:
    venv = gym.make_vec(IDS[0], num_envs=4, vectorization_mode="vector_entry_point", render_mode="human", render_grid=4)
    venv.reset(seed=0)
    venv.step(np.zeros(venv.action_space.shape))
    surface = pygame.display.get_surface()
    assert surface is not None and surface.get_size()[0] > 1000
    venv.close()
    assert not pygame.display.get_init() or pygame.display.get_surface() is None


def test_missing_pygame_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    env = gym.make(IDS[0])
    monkeypatch.setitem(sys.modules, "pygame", None)
    with pytest.raises(ImportError, match=re.escape(install_hint("render"))):
        make_renderer(env.unwrapped.task, "rgb_array")


def test_the_renderer_draws_the_scene_it_is_given() -> None:
    from bluesky_gym.envs.registry import entry, multiagent_entry
    from bluesky_gym.render.scene import MapScene
    from bluesky_gym.render.scenes.generic import generic_scene

    env = gym.make("MergeEnv-v0", render_mode="rgb_array")
    env.reset(seed=0)
    env.render()
    assert env.unwrapped._renderer.scene is entry("MergeEnv-v0").scene_builder()
    drawn: list[int] = []

    def scene(task, i: int) -> MapScene:
        drawn.append(i)
        return generic_scene(task, i)

    renderer = make_renderer(env.unwrapped.task, "rgb_array", scene=scene)
    _check_frame(renderer.render(0), min_colors=10)
    assert drawn == [0]
    assert make_renderer(env.unwrapped.task, "rgb_array").scene is generic_scene
    with pytest.raises(TypeError, match="scene builder"):
        make_renderer(env.unwrapped.task, "rgb_array", scene="merge")  # type: ignore[arg-type]

    from bluesky_gym.environments.merge.multiagent import MergeCentralisedEnv

    ma_env = MergeCentralisedEnv(render_mode="rgb_array")
    ma_env.reset(seed=0)
    _check_frame(ma_env.render())
    assert ma_env._renderer.scene is multiagent_entry("merge_v0").scene_builder()


def test_unknown_render_mode_is_rejected() -> None:
    env = gym.make(IDS[0])
    with pytest.raises(ValueError):
        make_renderer(env.unwrapped.task, "ascii")


# --- videos -------------------------------------------------------------------------------------
def _frames(env_id: str, n: int) -> list[np.ndarray]:
    env = gym.make(env_id, render_mode="rgb_array")
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    out = [env.render()]
    for _ in range(n - 1):
        _, _, te, tr, _ = env.step(_act(env, rng))
        out.append(env.render())
        if te or tr:
            env.reset()
    env.close()
    return out


def test_gif_writer(tmp_path) -> None:
    from PIL import Image

    frames = _frames(IDS[0], 4)
    path = write_video(tmp_path / "sub" / "a.gif", frames, fps=5)
    with Image.open(path) as im:
        assert im.n_frames == 4
        assert im.size == (frames[0].shape[1], frames[0].shape[0])
        im.seek(3)
        last = np.asarray(im.convert("RGB"))
    assert np.abs(last.astype(int) - frames[3].astype(int)).mean() < 3.0
    with pytest.raises(ValueError, match="format"):
        write_video(tmp_path / "a.avi", frames)
    with pytest.raises(ValueError, match="no frames"):
        write_video(tmp_path / "b.gif", [])
    with pytest.raises(ValueError):
        write_video(tmp_path / "c.gif", [frames[0][:, :, 0]])


def test_mp4_writer(tmp_path) -> None:
    pytest.importorskip("imageio_ffmpeg")
    import imageio.v2 as imageio

    frames = _frames(IDS[0], 3)
    path = write_video(tmp_path / "a.mp4", frames, fps=5)
    reader = imageio.get_reader(path)
    assert reader.count_frames() == 3
    reader.close()


def test_mp4_without_ffmpeg_says_what_to_install(tmp_path, monkeypatch: pytest.MonkeyPatch) -> None:
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "imageio_ffmpeg" else real(name, *a))
    with pytest.raises(ImportError, match="imageio-ffmpeg"):
        write_video(tmp_path / "a.mp4", _frames(IDS[0], 1))


def test_record_video_wrapper(tmp_path) -> None:
    """Gymnasium's RecordVideo works with the render extra (which installs MoviePy)."""
    import moviepy  # noqa: F401  (the render extra installs it; a missing MoviePy is a broken install)

    folder = tmp_path / "videos"  # a new folder: RecordVideo warns when it overwrites
    env = gym.wrappers.RecordVideo(gym.make("DescentEnv-v0", render_mode="rgb_array"), str(folder), episode_trigger=lambda k: True)
    env.reset(seed=0)
    for _ in range(3):
        env.step(env.action_space.sample())
    env.close()
    videos = list(folder.glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 1000


def test_panel_shows_info_values_with_units() -> None:
    from bluesky_gym.render.renderer import info_line

    assert info_line("average_drift", 0.145) == ("mean |drift|", "8.3 deg")
    assert info_line("final_altitude", 304.8) == ("final altitude", "305 m (1000 ft)")
    assert info_line("faf_reach", True) == ("reached FAF", "yes")
    assert info_line("average_drift", float("nan")) == ("mean |drift|", "-")
    assert info_line("something_new", 2.5) == ("something_new", "2.500")
    assert info_line("average_route_deviation_nm", 0.1934) == ("mean route dev.", "0.19 NM")


def test_every_info_value_of_the_environments_has_a_panel_label() -> None:
    """The panel's label column is narrow: every task's info entry has a short label and a unit, not its key."""
    from bluesky_gym.envs.registry import ENVIRONMENTS, resolve
    from bluesky_gym.render.renderer import INFO_DISPLAY

    keys = {k for entry in ENVIRONMENTS for k in resolve(entry.task).info_keys if k != "total_reward"}
    assert keys and keys <= set(INFO_DISPLAY), sorted(keys - set(INFO_DISPLAY))
    assert all(len(label) <= 16 for label, _ in INFO_DISPLAY.values())


# --- the command --------------------------------------------------------------------------------
def test_render_command_is_seedable(tmp_path) -> None:
    from bluesky_gym.cli import main

    env_id = IDS[-1]
    a, b, c = tmp_path / "a.gif", tmp_path / "b.gif", tmp_path / "c.gif"
    common = ["render", env_id, "--episodes", "2", "--max-frames", "6", "--max-steps", "4"]
    assert main([*common, "--out", str(a), "--seed", "3"]) == 0
    assert main([*common, "--out", str(b), "--seed", "3"]) == 0
    assert main([*common, "--out", str(c), "--seed", "4"]) == 0
    assert a.read_bytes() == b.read_bytes()
    assert a.read_bytes() != c.read_bytes()
    from PIL import Image

    with Image.open(a) as im:
        assert im.n_frames == 6


def test_render_command_grid_and_errors(tmp_path, capsys: pytest.CaptureFixture[str]) -> None:
    from bluesky_gym.cli import main

    out = tmp_path / "grid.gif"
    assert main(["render", IDS[0], "--grid", "2", "--max-frames", "3", "--out", str(out)]) == 0
    assert out.exists()
    assert main(["render", "NoSuchEnv-v0", "--out", str(tmp_path / "x.gif")]) == 2
    assert main(["render", IDS[0], "--policy", "no/such/model.zip", "--out", str(tmp_path / "y.gif")]) == 2
    assert main(["render", IDS[0], "--out", str(tmp_path / "z.avi")]) == 2
    assert main(["render", IDS[0], "--option", "no_such_option=1", "--out", str(tmp_path / "o.gif")]) == 2
    err = capsys.readouterr().err
    assert "unknown environment" in err and "model .zip" in err and "unsupported video format" in err and "no_such_option" in err


def test_render_command_with_a_model(tmp_path) -> None:
    sb3 = pytest.importorskip("stable_baselines3")
    from bluesky_gym.cli import main

    env_id = IDS[0]
    model = sb3.PPO("MultiInputPolicy", gym.make(env_id), n_steps=8, batch_size=8, device="cpu")
    model.save(tmp_path / "model.zip")
    out = tmp_path / "model.gif"
    assert main(["render", env_id, "--policy", str(tmp_path / "model.zip"), "--max-frames", "3", "--out", str(out)]) == 0
    assert out.exists()


@pytest.mark.parametrize("env_id", IDS)
def test_gymnasium_checker_accepts_the_frames(env_id: str) -> None:
    import warnings

    from gymnasium.utils.env_checker import check_env

    env = gym.make(env_id, render_mode="rgb_array")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)  # includes gymnasium's render checks
    assert not [str(w.message) for w in caught if "render" in str(w.message).lower()]
    env.close()
