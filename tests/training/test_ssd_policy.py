"""The ``ssd`` reference policy: the ``mvp`` policy's mapping flying BlueSky's SSD resolution (``RESO SSD``)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pyclipper")

from bluesky_gym.core.ssd import SSDResolver
from bluesky_gym.training.evaluation import make_policy, reference_scores
from bluesky_gym.training.policies import SELECTABLE_REFERENCES, optional_reference_names
from tests.training.test_mvp_policy import _head_on_separation


def test_ssd_is_a_selectable_reference_where_mvp_is() -> None:
    assert "ssd" in SELECTABLE_REFERENCES
    assert "ssd" in optional_reference_names("HorizontalCREnv-v0") and "ssd" not in optional_reference_names("DescentEnv-v0")
    policy = make_policy("ssd", "HorizontalCREnv-v0")
    assert policy.name == "ssd" and isinstance(policy.resolver, SSDResolver)


def test_ssd_resolves_a_head_on_conflict() -> None:
    """HorizontalCR with one head-on intruder: the ssd policy keeps the intruder out of the zone, the nominal policy does not."""
    with_ssd = _head_on_separation("HorizontalCREnv-v0", True, method="SSD")
    without = _head_on_separation("HorizontalCREnv-v0", False)
    assert np.all(with_ssd >= 1.0), with_ssd
    assert np.all(with_ssd > without), (with_ssd, without)


def test_reference_scores_add_ssd_on_request() -> None:
    refs = reference_scores("HorizontalCREnv-v0", 1, None, extra=("ssd",))
    assert set(refs) == {"random", "classical", "mvp", "ssd"} and refs["ssd"]["policy"] == "ssd"
