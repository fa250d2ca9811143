"""A measurement's crib channels against the site's detector (light: the schemas only).

A ``MeasuredPassage`` with ``channels`` must name exactly the site's ``detector.cribs`` ids,
in any order. ``channels_mismatch`` says what is wrong in one line, or None: the CLI turns
it into exit status 2, the twin into an ``invalid_measurement`` ServiceError (field
``channels``), the diagnoser into a ``MeasurementError``.

Channels are fitted on a rail on discrete supports or slab (the twin simulates the cribs
there); at a site on a rigid or compliant foundation a channel measurement is answered with
``CHANNELS_NEED_TRACK`` (``channels_problem`` says either).

    >>> from schemas.diagnosis import MeasuredPassage
    >>> m = MeasuredPassage(passage_id="p", sample_rate=1e4, t_start=0.0,
    ...                     channels={"ch1": [0.0] * 16, "ch9": [0.0] * 16})
    >>> print(channel_mismatch(m.channel_ids, ("ch1", "ch2")))
    the ids must be the site's detector cribs ch1, ch2: missing ch2; extra ch9
"""

from __future__ import annotations

from collections.abc import Sequence

from schemas.diagnosis import MeasuredPassage
from schemas.site import SiteConfig

CHANNELS_FIELD = "channels"

CHANNELS_NEED_TRACK = (
    "crib channels are diagnosed on a rail on discrete supports or slab only: at a rigid or "
    "compliant site measure the contact force (t_s,force_N)"
)
"""The answer to channels at a site whose rail is not modelled (docs/service.md)."""


def site_cribs(site: SiteConfig) -> tuple[str, ...]:
    """The site's crib ids, in the site file's order (none without a detector)."""
    return tuple(c.id for c in site.detector.cribs) if site.detector is not None else ()


def channel_mismatch(ids: Sequence[str], cribs: Sequence[str]) -> str | None:
    """One line saying how channel ``ids`` differ from the site's ``cribs``, or None."""
    if not cribs:
        return (
            f"the site has no detector, so no crib channels "
            f"({', '.join(ids)}); measure the contact force (force) there"
        )
    missing = [c for c in cribs if c not in ids]
    extra = [i for i in ids if i not in cribs]
    if not missing and not extra:
        return None
    parts = []
    if missing:
        parts.append(f"missing {', '.join(missing)}")
    if extra:
        parts.append(f"extra {', '.join(extra)}")
    return f"the ids must be the site's detector cribs {', '.join(cribs)}: " + "; ".join(parts)


def channels_mismatch(measured: MeasuredPassage, site: SiteConfig) -> str | None:
    """How the channel ids of ``measured`` differ from the cribs of ``site``, in one line
    (field ``channels``), or None: they match, or it is a contact-force measurement."""
    if measured.channels is None:
        return None
    return channel_mismatch(measured.channel_ids, site_cribs(site))


def channels_problem(measured: MeasuredPassage, site: SiteConfig) -> str | None:
    """Why ``measured``'s channels cannot be diagnosed at ``site`` (ids that are not its
    cribs, or a site whose rail is not modelled), in one line, or None."""
    mismatch = channels_mismatch(measured, site)
    if mismatch is not None or measured.channels is None:
        return mismatch
    if site.foundation.kind not in ("discrete", "slab"):
        return CHANNELS_NEED_TRACK
    return None
