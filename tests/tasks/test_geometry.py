"""Scalar fast paths of the scenario geometry equal the numpy helpers to the last bit."""

from __future__ import annotations

import numpy as np

from bluesky_gym.tasks.geometry import (
    point_at_distance,
    point_at_distance_scalar,
    polygon_area,
    random_convex_polygon,
    sort_points_clockwise,
)


def test_scalar_polygon_generator_equals_the_numpy_helpers() -> None:
    for seed in range(300):
        rng_a, rng_b = np.random.default_rng(seed), np.random.default_rng(seed)
        radius = 1.0 + 30.0 * rng_a.uniform()
        rng_b.uniform()
        min_area = 0.6 * np.pi * radius * radius
        poly = random_convex_polygon(rng_a, radius, min_area)
        # The same draws through the numpy helpers.
        pts = [np.array([radius * np.cos(a), radius * np.sin(a)]) for a in 2 * np.pi * rng_b.uniform(0.0, 1.0, 3)]
        ref = sort_points_clockwise(pts)
        while polygon_area(ref) < min_area:
            a = 2 * np.pi * rng_b.uniform(0.0, 1.0)
            pts.append(np.array([radius * np.cos(a), radius * np.sin(a)]))
            ref = sort_points_clockwise(pts)
        np.testing.assert_array_equal(poly, ref)
        assert rng_a.uniform() == rng_b.uniform()  # same number of draws


def test_scalar_point_at_distance_equals_the_numpy_form() -> None:
    rng = np.random.default_rng(8)
    lat, lon = rng.uniform(-80, 80, 2000), rng.uniform(-180, 180, 2000)
    d, b = rng.integers(0, 2000, 2000), rng.integers(0, 360, 2000)
    ref_lat, ref_lon = point_at_distance(lat, lon, d, b)
    got = np.array([point_at_distance_scalar(*args) for args in zip(lat, lon, d, b)])
    np.testing.assert_array_equal(got[:, 0], ref_lat)
    np.testing.assert_array_equal(got[:, 1], ref_lon)
