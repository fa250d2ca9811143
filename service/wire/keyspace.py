"""The Zenoh key space of one site (see ``schemas.messages`` for the payloads).

>>> k = SiteKeys("km12")
>>> k.passage, k.force("t1-a0-r")
('railtwin/km12/passage', 'railtwin/km12/force/t1-a0-r')
>>> k.rail, HEALTH_KEY
('railtwin/km12/rail', 'railtwin/health')
>>> k.measured, k.diagnosis("t1-a0-r")
('railtwin/km12/measured', 'railtwin/km12/diagnosis/t1-a0-r')
>>> k.diagnoses
'railtwin/km12/diagnoses'
"""

from __future__ import annotations

from dataclasses import dataclass

ROOT = "railtwin"
HEALTH_KEY = f"{ROOT}/health"


@dataclass(frozen=True)
class SiteKeys:
    """Keys of the site ``site_id``; per-passage keys end with the passage id."""

    site_id: str

    @property
    def prefix(self) -> str:
        return f"{ROOT}/{self.site_id}"

    @property
    def passage(self) -> str:
        """Where wheel passages come in."""
        return f"{self.prefix}/passage"

    @property
    def measured(self) -> str:
        """Where measured passages (``MeasuredPassage``, for the diagnosis) come in."""
        return f"{self.prefix}/measured"

    @property
    def alive(self) -> str:
        """The twin's liveliness token: present while it serves this site."""
        return f"{self.prefix}/alive"

    @property
    def error(self) -> str:
        return f"{self.prefix}/error"

    @property
    def health(self) -> str:
        """The site's own health queryable (``railtwin/health`` answers for every site)."""
        return f"{self.prefix}/health"

    @property
    def rail(self) -> str:
        return f"{self.prefix}/rail"

    @property
    def all_outputs(self) -> str:
        """Everything the service publishes for this site."""
        return f"{self.prefix}/**"

    def force(self, passage_id: str) -> str:
        return f"{self.prefix}/force/{passage_id}"

    def indentation(self, passage_id: str) -> str:
        return f"{self.prefix}/indentation/{passage_id}"

    def result(self, passage_id: str) -> str:
        return f"{self.prefix}/result/{passage_id}"

    def diagnosis(self, passage_id: str) -> str:
        return f"{self.prefix}/diagnosis/{passage_id}"

    @property
    def diagnoses(self) -> str:
        """The catch-up queryable: ``?since=<unix s>`` → one Diagnosis per reply, each on
        ``diagnosis(<passage_id>)``."""
        return f"{self.prefix}/diagnoses"

    def kind_of(self, key: str) -> str | None:
        """``"force"``, ``"result"``, ``"error"``, ... for a key of this site, else None."""
        if not key.startswith(self.prefix + "/"):
            return None
        return key[len(self.prefix) + 1 :].split("/", 1)[0]
