"""The fleet's Zenoh keys (docs/fleet.md; CONTRACTS: wheel identity).

>>> alarm_key("V123", 2, "left"), wheel_key("V123/2/left")
('railtwin/fleet/alarm/V123/2/left', 'railtwin/fleet/wheel/V123/2/left')
>>> wheel_id_of_key("railtwin/fleet/wheel/V123/2/left")
'V123/2/left'
>>> site_of_key("railtwin/km12/diagnosis/t1-a0-l")
'km12'
"""

from __future__ import annotations

import re

ROOT = "railtwin"
FLEET = f"{ROOT}/fleet"
ALARM_PREFIX = f"{FLEET}/alarm"
WHEEL_PREFIX = f"{FLEET}/wheel"
ALARMS_KEY = f"{FLEET}/alarms"
"""Queryable: the fleet's alarms (open ones; ``?all=true`` for every alarm)."""
WHEEL_QUERYABLE = f"{WHEEL_PREFIX}/*/*/*"
DIAGNOSES_SUB = f"{ROOT}/*/diagnosis/**"
"""Every site's diagnoses."""
RESULTS_SUB = f"{ROOT}/*/result/**"
"""Every site's results (the fleet reads only the passage's speed from them)."""
CATCH_UP_SELECTOR = f"{ROOT}/*/diagnoses"
"""Each twin's queryable answering ``?since=<unix s>`` with the diagnoses it made since."""
HEALTH_SELECTOR = f"{ROOT}/*/health"
ALIVE_SUB = f"{ROOT}/*/alive"
"""Twins' liveliness tokens: a token appearing triggers a catch-up from that site."""

_CHUNK = re.compile(r"^[A-Za-z0-9_.\-]{1,96}$")
_WHEEL_ID = re.compile(r"^([A-Za-z0-9_.\-]{1,96})/([1-9][0-9]{0,8})/(left|right)$")


class WheelIdError(ValueError):
    """A string that is not ``<vehicle_id>/<wheelset>/<side>``."""


def parse_wheel_id(text: str) -> tuple[str, int, str]:
    """(vehicle_id, wheelset, side) of ``"V123/2/left"``; WheelIdError if malformed."""
    m = _WHEEL_ID.match(text)
    if m is None:
        raise WheelIdError(
            f"{text!r} is not a wheel id <vehicle_id>/<wheelset>/<side> (vehicle_id: letters, "
            "digits, _ . -; wheelset: an integer >= 1; side: left or right)"
        )
    return m.group(1), int(m.group(2)), m.group(3)


def catch_up_key(site_id: str) -> str:
    return f"{ROOT}/{site_id}/diagnoses"


def alarm_key(vehicle_id: str, wheelset: int, side: str) -> str:
    return f"{ALARM_PREFIX}/{vehicle_id}/{wheelset}/{side}"


def wheel_key(wheel_id: str) -> str:
    parse_wheel_id(wheel_id)
    return f"{WHEEL_PREFIX}/{wheel_id}"


def wheel_id_of_key(key: str) -> str | None:
    """The wheel id of a concrete ``railtwin/fleet/wheel/V/2/left`` key, else None."""
    if not key.startswith(WHEEL_PREFIX + "/"):
        return None
    rest = key[len(WHEEL_PREFIX) + 1 :]
    return rest if _WHEEL_ID.match(rest) else None


def site_of_key(key: str) -> str | None:
    """The site of a ``railtwin/<site>/...`` key (None if it is not one)."""
    parts = key.split("/")
    if len(parts) < 3 or parts[0] != ROOT or not _CHUNK.match(parts[1]):
        return None
    return parts[1]
