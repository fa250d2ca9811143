"""The error of a measurement that cannot be diagnosed (light: no physics imported).

Raised by ``service.physics.diagnosis`` in the physics worker, sent across to the twin, which
answers it with an ``invalid_measurement`` ServiceError naming ``field``.
"""

from __future__ import annotations


class MeasurementError(ValueError):
    """A measurement that cannot be diagnosed; ``field`` names what is wrong."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message
