"""The conflict-resolution methods of the core, by their BlueSky ``RESO`` name.

Every method is one :class:`~bluesky_gym.core.resolution.ConflictResolver` subclass: it gives
``resolve(state, conflicts, vsmin, vsmax)`` (BlueSky's ``resolve(conf, ownship, intruder)``:
the resolution track, speed, vertical speed and altitude of every aircraft), and the base class
keeps BlueSky's ASAS bookkeeping (when the values are renewed, ``resumenav``, waypoint recovery)
for all of them. :class:`~bluesky_gym.core.resolution.AsasConfig` names the method
(``method="EBY"``), the scenario player selects it with ``RESO <name>`` and
:meth:`bluesky_gym.core.Simulator.set_conflict_resolution` flies it.

* ``MVP``: :class:`~bluesky_gym.core.resolution.MVPResolver`, BlueSky 1.1.1's Modified Voltage Potential.
* ``EBY``: :class:`~bluesky_gym.core.eby.EbyResolver`, BlueSky's Eby plugin (with the fix it needs to run).
* ``SWARM``: :class:`~bluesky_gym.core.swarm.SwarmResolver`, BlueSky's Swarm plugin (with the fixes it needs to run).
* ``SSD``: :class:`~bluesky_gym.core.ssd.SSDResolver`, BlueSky's SSD plugin (with the fixes it needs to run; pyclipper, the ``ssd`` extra).

Adding a method: write its resolver class (a subclass with ``name = "NAME"`` and ``resolve``;
``resolve_pairs`` too if it supports ``pair_search="grid"``, otherwise set
``pair_searches = ("all-pairs",)``), then add one entry ``"NAME": NameResolver`` to
:data:`RESOLVERS`. ``RESO NAME`` in scenario files and ``AsasConfig(method="NAME")`` then work.
"""

from __future__ import annotations

from bluesky_gym.core.eby import EbyResolver
from bluesky_gym.core.resolution import ConflictResolver, MVPResolver
from bluesky_gym.core.ssd import SSDResolver
from bluesky_gym.core.swarm import SwarmResolver

#: The resolution methods by ``RESO`` name.
RESOLVERS: dict[str, type[ConflictResolver]] = {
    "MVP": MVPResolver,
    "EBY": EbyResolver,
    "SWARM": SwarmResolver,
    "SSD": SSDResolver,
}


def resolver_class(method: str) -> type[ConflictResolver]:
    """The resolver of ``RESO method``.

    Raises:
        ValueError: A method the core does not have.
    """
    try:
        return RESOLVERS[method]
    except KeyError:
        raise ValueError(f"resolution method {method!r} not known; choose one of {', '.join(RESOLVERS)}") from None


__all__ = ["RESOLVERS", "resolver_class"]
