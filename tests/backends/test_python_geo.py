"""The core's copy of BlueSky's Python geo forms equals BlueSky's own, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from bluesky_gym.core import geo

_geo = pytest.importorskip("bluesky.tools.geo._geo", reason="needs the BlueSky simulator (the 'bluesky' extra)")

pytestmark = pytest.mark.bluesky


@pytest.mark.parametrize("hemispheres", ["mixed", "north"])
def test_qdrdist_python_is_bitwise_bluesky(hemispheres: str) -> None:
    rng = np.random.default_rng(0)
    lat1, lat2 = rng.uniform(-80, 80, (2, 2000))
    lon1, lon2 = rng.uniform(-170, 170, (2, 2000))
    if hemispheres == "north":
        lat1, lat2 = np.abs(lat1), np.abs(lat2)
    q_ref, d_ref = _geo.qdrdist(lat1, lon1, lat2, lon2)
    q, d = geo.qdrdist_python(lat1, lon1, lat2, lon2)
    np.testing.assert_array_equal(q, q_ref)
    np.testing.assert_array_equal(d, d_ref)
    np.testing.assert_array_equal([geo.rwgs84_py(x) for x in lat1], _geo.rwgs84(lat1))
