"""The scenario and kwik geometry equals its readable numpy oracle to the last bit."""

from __future__ import annotations

import numpy as np
import pytest

from bluesky_gym.tasks import geometry
from bluesky_gym.tasks.geometry import polygon_area, random_convex_polygon
from tests.oracle import geometry as oracle


def test_scalar_polygon_generator_equals_the_numpy_helpers() -> None:
    for seed in range(300):
        rng_a, rng_b = np.random.default_rng(seed), np.random.default_rng(seed)
        radius = 1.0 + 30.0 * rng_a.uniform()
        rng_b.uniform()
        min_area = 0.6 * np.pi * radius * radius
        poly = random_convex_polygon(rng_a, radius, min_area)
        # The same draws through the numpy helpers.
        pts = [np.array([radius * np.cos(a), radius * np.sin(a)]) for a in 2 * np.pi * rng_b.uniform(0.0, 1.0, 3)]
        ref = oracle.sort_points_clockwise(pts)
        while polygon_area(ref) < min_area:
            a = 2 * np.pi * rng_b.uniform(0.0, 1.0)
            pts.append(np.array([radius * np.cos(a), radius * np.sin(a)]))
            ref = oracle.sort_points_clockwise(pts)
        np.testing.assert_array_equal(poly, ref)
        assert rng_a.uniform() == rng_b.uniform()  # same number of draws


def test_point_at_distance_equals_the_numpy_form() -> None:
    rng = np.random.default_rng(8)
    lat, lon = rng.uniform(-80, 80, 2000), rng.uniform(-180, 180, 2000)
    d, b = rng.integers(0, 2000, 2000), rng.integers(0, 360, 2000)
    got, want = geometry.point_at_distance(lat, lon, d, b), oracle.point_at_distance(lat, lon, d, b)
    np.testing.assert_array_equal(got[0], want[0], strict=True)
    np.testing.assert_array_equal(got[1], want[1], strict=True)
    # Broadcasting (one start, many draws) and one point.
    got = geometry.point_at_distance(52.0, 4.0, d.reshape(40, 50), b.reshape(40, 50))
    want = oracle.point_at_distance(52.0, 4.0, d.reshape(40, 50), b.reshape(40, 50))
    np.testing.assert_array_equal(got[0], want[0], strict=True)
    one = geometry.point_at_distance(52.0, 4.0, 120, 37)
    assert float(one[0]) == float(oracle.point_at_distance(52.0, 4.0, 120, 37)[0])
    assert float(one[1]) == float(oracle.point_at_distance(52.0, 4.0, 120, 37)[1])


def test_kwik_forms_equal_the_numpy_forms() -> None:
    rng = np.random.default_rng(9)
    lata, lona = 52.0 + rng.normal(0, 2, (30, 1)), rng.uniform(-180, 180, (30, 1))
    latb, lonb = lata + rng.normal(0, 2, (30, 12)), rng.uniform(-180, 180, (30, 12))  # across the date line too
    np.testing.assert_array_equal(geometry.ref_kwikdist(lata, lona, latb, lonb), oracle.ref_kwikdist(lata, lona, latb, lonb), strict=True)
    qdr, dist = geometry.ref_kwikqdrdist(lata, lona, latb, lonb)
    want_qdr, want_dist = oracle.ref_kwikqdrdist(lata, lona, latb, lonb)
    np.testing.assert_array_equal(qdr, want_qdr, strict=True)
    np.testing.assert_array_equal(dist, want_dist, strict=True)
    # More than two dimensions, and a shape mismatch.
    a3, b3 = lata.reshape(5, 6, 1), latb.reshape(5, 6, 12)
    np.testing.assert_array_equal(geometry.ref_kwikdist(a3, 4.0, b3, 5.0), oracle.ref_kwikdist(a3, 4.0, b3, 5.0), strict=True)
    with pytest.raises(ValueError, match="broadcast"):
        geometry.ref_kwikdist(lata[:4], lona, latb, lonb)
    # Scalars in, scalars out.
    assert float(geometry.ref_kwikdist(52.0, 4.0, 52.5, 4.5)) == float(oracle.ref_kwikdist(52.0, 4.0, 52.5, 4.5))
