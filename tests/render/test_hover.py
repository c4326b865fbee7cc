"""The aircraft under the mouse pointer is labelled in the "human" window; rgb_array frames never are."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from bluesky_gym.registration import available_envs

pygame = pytest.importorskip("pygame")

from bluesky_gym.render import palette  # noqa: E402
from bluesky_gym.render.backend import WINDOW  # noqa: E402
from bluesky_gym.render.renderer import HOVER_PX, MAP_SIZE, draw_map, surface_to_array  # noqa: E402
from bluesky_gym.render.scene import MapAircraft, MapScene  # noqa: E402
from bluesky_gym.render.views import MapView  # noqa: E402


def _scene() -> tuple[MapScene, MapView]:
    """An ownship and two intruders; only traffic within 5 NM is labelled, so both intruders are not."""
    view = MapView.fit(52.0, 4.0, 50.0, (0, 0, 600, 600))  # 6 px/NM
    near = view.latlon_of_nm(20.0, 10.0)
    far = view.latlon_of_nm(-25.0, -20.0)
    aircraft = [
        MapAircraft(0, 52.0, 4.0, hdg=90.0, trk=90.0, gs=200.0, alt=3000.0, callsign="OWN1", role="own", ring_nm=2.5),
        MapAircraft(1, *near, hdg=270.0, trk=270.0, gs=150.0, alt=3048.0, callsign="KLM123", ring_nm=2.5),
        MapAircraft(2, *far, hdg=0.0, trk=0.0, gs=150.0, alt=3048.0, callsign="BAW9", ring_nm=2.5),
    ]
    return MapScene(52.0, 4.0, 50.0, aircraft=aircraft, follow=None, label_range_nm=5.0), view


def _draw(scene: MapScene, view: MapView, hover: tuple[float, float] | None) -> np.ndarray:
    surf = pygame.Surface((600, 600))
    draw_map(surf, view, scene, {}, hover=hover)
    return surface_to_array(surf)


def test_hover_labels_the_aircraft_under_the_pointer_and_nothing_else() -> None:
    scene, view = _scene()
    plain = _draw(scene, view, None)
    x, y = view.point(scene.aircraft[1].lat, scene.aircraft[1].lon)
    # The pointer a few pixels off the symbol: the label (callsign and FL/speed line) appears.
    hovered = _draw(scene, view, (x + 4, y - 3))
    rows, cols = np.nonzero(np.any(hovered != plain, axis=-1))
    assert rows.size > 100, "hovering an aircraft must draw its label"
    # Everything that changed is the label, right of and below the symbol ...
    assert cols.min() >= x + 8 and rows.min() >= y + 4 and rows.max() <= y + 32 and cols.max() <= x + 110
    # ... with both lines: the callsign in the symbol's colour and the flight level / speed below.
    label = hovered[round(y) + 4 : round(y) + 16, round(x) + 9 : round(x) + 70]
    assert np.any(np.all(np.abs(label.astype(int) - np.array(palette.INTRUDER)) <= 20, axis=-1))
    assert rows.max() >= y + 20, "the flight level and ground speed line is missing"
    # The same label as an aircraft the scene labels itself (with details).
    scene_all = MapScene(**{**vars(scene), "label_range_nm": None, "traffic_details": True})
    shown = _draw(scene_all, view, None)
    box = (slice(round(y) + 4, round(y) + 33), slice(round(x) + 8, round(x) + 111))
    assert np.array_equal(hovered[box], shown[box])


def test_hover_away_from_aircraft_changes_nothing() -> None:
    scene, view = _scene()
    plain = _draw(scene, view, None)
    x, y = view.point(scene.aircraft[1].lat, scene.aircraft[1].lon)
    for point in [(5.0, 5.0), (x + HOVER_PX + 2, y), (300.0, 300.0 + HOVER_PX + 2), (-50.0, 900.0)]:
        assert np.array_equal(_draw(scene, view, point), plain), f"hover at {point} changed the picture"
    # The ownship is labelled anyway: hovering it only redraws its own label.
    own = _draw(scene, view, (300.0, 300.0))
    assert np.array_equal(own, plain)


def test_hover_picks_the_nearest_aircraft() -> None:
    scene, view = _scene()
    x, y = view.point(scene.aircraft[1].lat, scene.aircraft[1].lon)
    close = MapAircraft(3, *view.latlon_of_nm(21.5, 10.0), hdg=0.0, trk=0.0, gs=100.0, alt=0.0, callsign="NEAR2")
    scene.aircraft.append(close)
    plain = _draw(scene, view, None)
    first = _draw(scene, view, (x + 1, y))  # 1 px from aircraft 1, 8 px from aircraft 3
    second = _draw(scene, view, (x + 8, y))  # 7 px from aircraft 1, 1 px from aircraft 3
    c1 = np.nonzero(np.any(first != plain, axis=-1))[1]
    c2 = np.nonzero(np.any(second != plain, axis=-1))[1]
    assert c1.size and c2.size
    assert c1.min() >= x + 8 and c2.min() >= x + 9 + 8  # each label starts beside its own aircraft


def _traffic_in_view(scene: MapScene, view: MapView) -> tuple[float, float]:
    """Screen position of the last traffic aircraft well inside the map (room for its label)."""
    inside = [a for a in scene.aircraft if a.role != "own" and all(20 < c < MAP_SIZE[0] - 120 for c in view.point(a.lat, a.lon))]
    assert inside, "no traffic in the picture"
    return view.point(inside[-1].lat, inside[-1].lon)


#: Plan-view environments with traffic (Descent and VerticalCR are side views; PlanWaypoint and
#: StaticObstacle fly the ownship alone, which is always labelled).
TRAFFIC_MAP_IDS = [i for i in available_envs() if i.rsplit("-v", 1)[0] not in ("DescentEnv", "VerticalCREnv", "PlanWaypointEnv", "StaticObstacleEnv")]


@pytest.mark.parametrize("env_id", TRAFFIC_MAP_IDS)
def test_every_map_environment_labels_the_hovered_aircraft(env_id: str) -> None:
    options = {"labels": "none"} if env_id.startswith("RealTraffic") else {}
    env = gym.make(env_id, render_mode="rgb_array", **options)
    env.reset(seed=3)
    frame = env.render()
    renderer = env.unwrapped._renderer
    scene = renderer.scene(env.unwrapped.task, 0)
    assert isinstance(scene, MapScene)
    view = MapView.fit(scene.center_lat, scene.center_lon, scene.half_width_nm, (0, 0, *MAP_SIZE))
    if options:  # labels="none": the scene keeps the callsigns, for the pointer, but labels nothing
        assert not scene.labels and all(a.callsign for a in scene.aircraft)
    plain = surface_to_array(renderer.draw_frame(0))
    x, y = _traffic_in_view(scene, view)  # traffic labels show no flight level here, or nothing
    hovered = surface_to_array(renderer.draw_frame(0, hover=(x, y)))
    rows, cols = np.nonzero(np.any(hovered != plain, axis=-1))
    assert rows.size > 20 and rows.min() >= y + 4 and cols.min() >= x + 8, "the hovered aircraft's label must appear beside it"
    assert np.array_equal(surface_to_array(renderer.draw_frame(0, hover=(2.0, 2.0))), plain)
    assert np.array_equal(env.render(), frame), "rgb_array frames never show a hover label"
    env.close()


def _motion(pos: tuple[int, int]) -> None:
    pygame.event.post(pygame.event.Event(pygame.MOUSEMOTION, pos=pos, rel=(0, 0), buttons=(0, 0, 0)))


def test_the_window_passes_the_pointer_to_the_next_frame() -> None:
    env = gym.make("HorizontalCREnv-v0", render_mode="human")
    env.reset(seed=0)  # shows the first frame
    task, renderer = env.unwrapped.task, env.unwrapped._renderer
    scene = renderer.scene(task, 0)
    view = MapView.fit(scene.center_lat, scene.center_lon, scene.half_width_nm, (0, 0, *MAP_SIZE))
    x, y = (round(c) for c in _traffic_in_view(scene, view))
    env.render()
    plain = surface_to_array(pygame.display.get_surface())
    _motion((x, y))
    assert WINDOW.pointer(renderer._token) == (x, y)
    assert WINDOW.pointer(renderer._token + 1000) is None, "another renderer's frame is not under the pointer"
    env.render()
    hovered = surface_to_array(pygame.display.get_surface())
    changed = np.nonzero(np.any(hovered != plain, axis=-1))
    assert changed[0].size > 50 and changed[1].min() >= x + 8
    pygame.event.post(pygame.event.Event(pygame.WINDOWLEAVE))
    env.render()
    assert WINDOW.pointer(renderer._token) is None
    assert np.array_equal(surface_to_array(pygame.display.get_surface()), plain), "the label goes when the pointer leaves"
    env.close()


def test_hover_in_a_grid_labels_the_tile_under_the_pointer() -> None:
    from bluesky_gym.render.renderer import _tile_point

    assert _tile_point((10, 20), 1, (100, 50)) == (0, (10.0, 20.0))
    # Two tiles of 100 x 50 side by side, 4 px apart (small: not scaled).
    assert _tile_point((150, 10), 2, (100, 50)) == (1, (46.0, 10.0))
    assert _tile_point((102, 10), 2, (100, 50)) is None  # in the gap
    assert _tile_point((150, 52), 2, (100, 50)) is None  # below the tiles
    assert _tile_point((150, 80), 3, (100, 50)) is None  # where a fourth tile would be
    venv = gym.make_vec("HorizontalCREnv-v0", num_envs=4, vectorization_mode="vector_entry_point", render_mode="human", render_grid=4)
    venv.reset(seed=0)
    renderer = venv.unwrapped._renderer
    scene = renderer.scene(venv.unwrapped.task, 3)
    view = MapView.fit(scene.center_lat, scene.center_lon, scene.half_width_nm, (0, 0, *MAP_SIZE))
    x, y = _traffic_in_view(scene, view)
    venv.render()
    plain = surface_to_array(pygame.display.get_surface())
    size = plain.shape[1], plain.shape[0]
    full = 2 * 832 + 4, 2 * 608 + 4  # 2 x 2 tiles of 832 x 608, 4 px apart, then scaled to the window
    _motion((round((x + 836) * size[0] / full[0]), round((y + 612) * size[1] / full[1])))
    venv.render()
    hovered = surface_to_array(pygame.display.get_surface())
    rows, cols = np.nonzero(np.any(hovered != plain, axis=-1))
    assert rows.size > 20 and rows.min() > size[1] / 2 and cols.min() > size[0] / 2, "only the lower-right tile changes"
    venv.close()
