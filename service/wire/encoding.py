"""How the twin's messages travel: the Zenoh encoding of a model, a passage's series as JSON.

Shared by the twin, the physics workers (which make the series' JSON off the twin's GIL)
and the clients, so that none of them imports another for it.
"""

from __future__ import annotations

from typing import Literal

import zenoh
from pydantic import BaseModel

from schemas.messages import PassageResult, PassageSeries, encoding_schema

Quantity = Literal["force", "indentation"]

RESULT_ARRAYS = ("x", "force", "indentation", "y_c", "y_ck")
"""The per-sample arrays of a ``PassageResult`` (what a light result crosses without)."""


def json_encoding(model: type[BaseModel]) -> zenoh.Encoding:
    """``application/json;railtwin.<Model>/<version>``."""
    return zenoh.Encoding.APPLICATION_JSON.with_schema(encoding_schema(model))


def series_json(
    r: PassageResult, quantity: Quantity, first: int, last: int, chunk: int, chunks: int
) -> bytes:
    """Samples ``first:last`` of one quantity of ``r`` as a ``PassageSeries`` (JSON)."""
    values = r.force if quantity == "force" else r.indentation
    msg = PassageSeries.model_construct(
        site_id=r.site_id,
        passage_id=r.passage_id,
        quantity=quantity,
        unit="N" if quantity == "force" else "m",
        sample_rate=r.sample_rate,
        t_start=r.t_start,
        speed=r.speed,
        chunk=chunk,
        chunks=chunks,
        first_index=first,
        samples=len(r.x),
        x=r.x[first:last],
        values=values[first:last],
    )
    return msg.model_dump_json().encode()
