"""BlueSky 1.1.1's ASAS commands: conflict detection (``ASAS``/``CDMETHOD``) and resolution (``RESO MVP|EBY|SWARM|SSD``).

:class:`AsasState` follows what these commands do to BlueSky's settings, command after command, and
gives the :class:`~bluesky_gym.core.resolution.AsasConfig` the aircraft fly with. It keeps
BlueSky's bookkeeping: every detection method (off, STATEBASED, CSTATEBASED) keeps its own
protected zone and look-ahead time, and every resolution method (off, MVP, EBY, SWARM, SSD: the keys of
:data:`~bluesky_gym.core.resolvers.RESOLVERS`) its own factors and switches, starting from the
defaults when first selected. ``RMETHH``/``RMETHV`` change MVP's switches, which SWARM inherits;
with EBY, SSD (or resolution off) BlueSky ignores them. EBY, SWARM and SSD are BlueSky plugins (a
BlueSky scenario loads them with ``PLUGINS LOAD EBY`` first; the core has them built in and
ignores ``PLUGINS``), flown with the fixes that make them run (:mod:`bluesky_gym.core.eby`,
:mod:`bluesky_gym.core.swarm`, :mod:`bluesky_gym.core.ssd`). So ``ZONER`` before ``ASAS ON`` sets
the zone of "detection off" and is forgotten by STATEBASED, and ``RMETHH`` or ``RFACH`` before
the first ``RESO MVP`` have no effect on MVP. ``RSZONER``/``RSZONEDH`` set the resolution zone as
an absolute size, which a later ``ZONER``/``ZONEDH`` keeps (as BlueSky does, by rescaling the
factor).

Not supported (a :class:`ValueError` naming the reason): per-aircraft zones and look-ahead times,
priority rules (``PRIORULES ON`` while MVP or SWARM is selected; EBY ignores them, as in
BlueSky; SSD takes its default rule RS1 and refuses RS2..RS9), ``NORESO``/``RESOOFF`` aircraft
lists, resolution methods the core does not have, switching resolution off once it was on (BlueSky 1.1.1 then keeps flying the
last resolution of ``RESO OFF``, or finishes the resolutions in progress without detection after
``ASAS OFF``), and switching from one resolution method to another once one flew.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from bluesky_gym.core.command_text import parse_number, parse_time
from bluesky_gym.core.conflicts import DETECTORS, LOOKAHEAD, PZ_HEIGHT, PZ_RADIUS
from bluesky_gym.core.resolution import RESO_FACTOR, RMETHH_VALUES, RMETHV_VALUES, AsasConfig, ResolutionSettings
from bluesky_gym.core.resolvers import RESOLVERS
from bluesky_gym.core.ssd import check_priority
from bluesky_gym.core.units import FT, NM

#: BlueSky command names and their aliases -> the name used here.
ASAS_COMMANDS = {
    "ASAS": "CDMETHOD",
    "CDMETHOD": "CDMETHOD",
    "RESO": "RESO",
    "ZONER": "ZONER",
    "PZR": "ZONER",
    "RPZ": "ZONER",
    "PZRADIUS": "ZONER",
    "ZONEDH": "ZONEDH",
    "PZDH": "ZONEDH",
    "DHPZ": "ZONEDH",
    "PZHEIGHT": "ZONEDH",
    "DTLOOK": "DTLOOK",
    "DTNOLOOK": "DTNOLOOK",
    "RFACH": "RFACH",
    "RESOFACH": "RFACH",
    "HRFAC": "RFACH",
    "HRESOFAC": "RFACH",
    "RFACV": "RFACV",
    "RESOFACV": "RFACV",
    "RSZONER": "RSZONER",
    "RESOZONER": "RSZONER",
    "RSZONEDH": "RSZONEDH",
    "RESOZONEDH": "RSZONEDH",
    "RMETHH": "RMETHH",
    "RMETHV": "RMETHV",
    "PRIORULES": "PRIORULES",
    "NORESO": "NORESO",
    "RESOOFF": "RESOOFF",
}
#: Resolution methods (``RESO``): off and the core's methods.
RESOLUTION_METHODS = ("OFF", *RESOLVERS)
#: The methods whose switches ``RMETHH``/``RMETHV`` set and which follow priority rules (MVP and its subclass Swarm).
MVP_FAMILY = ("MVP", "SWARM")
#: ``PRIORULES`` priority codes BlueSky's MVP knows.
PRIORITY_CODES = ("FF1", "FF2", "FF3", "LAY1", "LAY2")


@dataclass
class _Detection:
    """One detection method's settings (BlueSky ``ConflictDetection`` instance)."""

    rpz: float = PZ_RADIUS  # m
    hpz: float = PZ_HEIGHT  # m
    lookahead: float = LOOKAHEAD  # s


@dataclass
class _Resolution:
    """One resolution method's settings (BlueSky ``ConflictResolution`` instance)."""

    resofach: float = RESO_FACTOR
    resofacv: float = RESO_FACTOR
    resorrelative: bool = True  # the resolution zone follows ZONER (False after RSZONER)
    resodhrelative: bool = True  # the same for ZONEDH / RSZONEDH
    switches: ResolutionSettings = field(default_factory=ResolutionSettings)


@dataclass
class AsasState:
    """BlueSky's ASAS settings while a scenario's commands run (all off at the start)."""

    detector: str = "OFF"
    resolution: str = "OFF"
    detection: dict[str, _Detection] = field(default_factory=lambda: {"OFF": _Detection()})
    resolutions: dict[str, _Resolution] = field(default_factory=lambda: {"OFF": _Resolution()})
    resolving_since: float | None = None  # time [s] from which detection and resolution were both on
    flown_method: str | None = None  # the resolution method that flew (since resolving_since)

    @property
    def cd(self) -> _Detection:
        """The selected detection method's settings."""
        return self.detection[self.detector]

    @property
    def cr(self) -> _Resolution:
        """The selected resolution method's settings."""
        return self.resolutions[self.resolution]

    def config(self) -> AsasConfig:
        """What the aircraft fly with now."""
        on = self.resolution != "OFF"
        s = replace(self.cr.switches, resofach=self.cr.resofach, resofacv=self.cr.resofacv)
        method = self.resolution if on else "MVP"
        return AsasConfig(None if self.detector == "OFF" else self.detector, on, s, self.cd.rpz, self.cd.hpz, self.cd.lookahead, method)

    def apply(self, name: str, args: list[str], t: float) -> AsasConfig:
        """Run one command (``name`` as in :data:`ASAS_COMMANDS`, its arguments) at time ``t`` [s].

        Returns:
            The configuration after it.

        Raises:
            ValueError: A value BlueSky refuses, or something the core does not model.
        """
        was = self.config().resolving
        value = args[0].strip().upper() if args and args[0].strip() else ""
        if name in ("ZONER", "ZONEDH", "DTLOOK", "DTNOLOOK") and len(args) > 1 and any(a.strip() for a in args[1:]):
            raise ValueError(f"per-aircraft values ({' '.join(args[1:])}) are not supported; set the value for all aircraft")
        if name == "CDMETHOD":
            if value:
                detector = "STATEBASED" if value == "ON" else value  # ON selects the first registered method
                if detector not in ("OFF", *DETECTORS):
                    raise ValueError(f"detection method {value!r} not known; choose one of ON, OFF, {', '.join(DETECTORS)}")
                self.detector = detector
                self.detection.setdefault(detector, _Detection())
        elif name == "RESO":
            if value:
                if value not in RESOLUTION_METHODS:
                    raise ValueError(f"resolution method {value!r} is not supported; choose one of {', '.join(RESOLUTION_METHODS)}")
                self.resolution = value
                self.resolutions.setdefault(value, _Resolution())
        elif name in ("ZONER", "ZONEDH", "DTLOOK", "DTNOLOOK"):
            self._zone(name, value)
        elif name in ("RFACH", "RFACV", "RSZONER", "RSZONEDH"):
            self._factor(name, value)
        elif name in ("RMETHH", "RMETHV"):
            if value:
                allowed = RMETHH_VALUES if name == "RMETHH" else RMETHV_VALUES
                if value not in allowed:
                    raise ValueError(f"{value!r} not understood; choose one of {', '.join(allowed)}")
                if self.resolution in MVP_FAMILY:  # the switches are MVP's; with EBY or resolution off BlueSky ignores them
                    sw = self.cr.switches
                    self.cr.switches = sw.with_methods(value, None) if name == "RMETHH" else sw.with_methods(None, value)
        elif name == "PRIORULES" and self.resolution == "SSD":
            if value:  # BlueSky's SSD takes the code with ON or OFF and refuses a missing one
                code = args[1].strip().upper() if len(args) > 1 else ""
                if not code:
                    raise ValueError(f"PRIORULES {value} needs a priority code with RESO SSD (RS1, the default rule)")
                check_priority(code)
        elif name == "PRIORULES":
            if value and value not in ("OFF", "FALSE", "0", "NO") and self.resolution in MVP_FAMILY:
                raise ValueError(f"priority rules are not supported by the core's {self.resolution} (PRIORULES OFF, the default, is)")
            code = args[1].strip().upper() if len(args) > 1 else ""
            if code and code not in PRIORITY_CODES:
                raise ValueError(f"priority code {code!r} not known; choose one of {', '.join(PRIORITY_CODES)}")
        elif name in ("NORESO", "RESOOFF"):
            if value:
                raise ValueError("aircraft lists that nobody avoids (NORESO) or that do not resolve (RESOOFF) are not supported")
        else:  # pragma: no cover - every name of ASAS_COMMANDS is handled above
            raise ValueError(f"unknown ASAS command {name}")
        now = self.config()
        if now.resolving and not was:
            self.resolving_since = t
            self.flown_method = now.method
        flew = self.resolving_since is not None and t > self.resolving_since
        if was and not now.resolving and flew:
            raise ValueError("switching conflict resolution off once it flew is not supported (BlueSky 1.1.1 then keeps flying the last resolution)")
        if now.resolving and flew and now.method != self.flown_method:
            raise ValueError(f"switching from RESO {self.flown_method} to RESO {now.method} once it flew is not supported")
        if now.resolving and not flew:
            self.flown_method = now.method
        if not now.resolving:
            self.resolving_since = None
            self.flown_method = None
        return now

    def _zone(self, name: str, value: str) -> None:
        if not value:
            return
        if name in ("ZONER", "ZONEDH"):
            number = parse_number(value, "a distance in NM" if name == "ZONER" else "a height in ft")
        else:
            number = parse_time(value)
        if number < 0.0:  # BlueSky: a negative value only shows the current one
            return
        cd, cr = self.cd, self.cr
        if name == "ZONER":
            old = cd.rpz
            cd.rpz = number * NM
            if not cr.resorrelative:  # BlueSky re-issues RSZONER with the old absolute resolution zone
                self._factor("RSZONER", repr(cr.resofach * old / NM))
        elif name == "ZONEDH":
            old = cd.hpz
            cd.hpz = number * FT
            if not cr.resodhrelative:
                self._factor("RSZONEDH", repr(cr.resofacv * old / FT))
        elif name == "DTLOOK":
            cd.lookahead = number
        # DTNOLOOK: stored by BlueSky 1.1.1 but used by no detection method

    def _factor(self, name: str, value: str) -> None:
        if not value:
            return
        number = parse_number(value, {"RSZONER": "a distance in NM", "RSZONEDH": "a height in ft"}.get(name, "a factor"))
        if not number > 0.0:
            raise ValueError(f"{name} must be > 0, got {value}")
        cr = self.cr
        if name == "RFACH":
            cr.resofach, cr.resorrelative = number, True
        elif name == "RFACV":
            cr.resofacv, cr.resodhrelative = number, True
        elif name == "RSZONER":  # an absolute resolution zone radius [NM]
            cr.resofach, cr.resorrelative = number / self.cd.rpz * NM, False
        else:  # RSZONEDH: an absolute resolution zone half height [ft]
            cr.resofacv, cr.resodhrelative = number / self.cd.hpz * FT, False
