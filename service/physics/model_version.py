"""The model version a diagnosis carries: railtwin's version, the track model, the site.

Two diagnoses of one passage made with the same version agree (the physics is
deterministic), so a re-analysis is keyed on (site, passage, version): the fingerprint
covers everything of the site file that the simulation or the verdict reads (the rail,
material, contact law, foundation, detector, measuring chain, limits, sample rate,
tolerance), and nothing else (its description, the schema version it was written in).

    >>> from schemas.site import SiteConfig
    >>> site = SiteConfig.model_validate({
    ...     "site_id": "km12", "length": 6.0, "output_sample_rate": 10000.0,
    ...     "rail": {"kind": "flat"}, "contact": "hertz",
    ...     "material": {"youngs_modulus": 2.14e11, "poisson_ratio": 0.3}})
    >>> v = model_version(site)
    >>> v.track, len(v.site)
    ('rigid', 16)
    >>> model_version(site.model_copy(update={"description": "renamed"})) == v
    True
"""

from __future__ import annotations

import hashlib
import json
from functools import cache
from importlib.metadata import PackageNotFoundError, version

from schemas.calibration import CalibrationRef
from schemas.diagnosis import ModelVersion
from schemas.site import SiteConfig, SiteFoundation

__all__ = [
    "calibration_ref",
    "foundation_fingerprint",
    "model_version",
    "package_version",
    "site_fingerprint",
]

NOT_PHYSICS = frozenset({"description", "schema_version"})
"""Fields of the site file that change no number of a diagnosis."""


@cache
def package_version() -> str:
    """railtwin's version (``unknown`` when it is not installed, e.g. run from a checkout)."""
    try:
        return version("railtwin")
    except PackageNotFoundError:
        return "unknown"


def site_fingerprint(site: SiteConfig) -> str:
    """16 hex digits of the SHA-256 of the site's physics and calibration, as canonical
    JSON (keys sorted; a file rail already read into its samples by ``load_site``)."""
    doc = site.model_dump(mode="json", exclude=set(NOT_PHYSICS))
    text = json.dumps(doc, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def foundation_fingerprint(foundation: SiteFoundation) -> str:
    """16 hex digits of the SHA-256 of the foundation's canonical JSON: a calibration's id.

    >>> from schemas.scenario import RigidFoundation
    >>> foundation_fingerprint(RigidFoundation(kind="rigid"))
    '175c6a2aadc0f3b8'
    """
    doc = foundation.model_dump(mode="json")
    text = json.dumps(doc, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def calibration_ref(site: SiteConfig) -> CalibrationRef:
    """The calibration a diagnosis at ``site`` uses: the site file's ``[calibration]`` table,
    or, without one, its foundation as drawn (``nominal``)."""
    if site.calibration is not None:
        return site.calibration.ref()
    return CalibrationRef(source="nominal", id=foundation_fingerprint(site.foundation), wheels=0)


def model_version(site: SiteConfig) -> ModelVersion:
    """The version of the model that diagnoses at ``site`` with this railtwin."""
    return ModelVersion(
        package=package_version(), track=site.foundation.kind, site=site_fingerprint(site)
    )
