"""Make ``train_160kmh.json``: a 32-wheel train at 160 km/h, one wheel with a measured flat.

    .venv/bin/python recordings/samples/make_sample_train.py

Eight cars of four axles (bogie wheelbase 2.5 m, bogie centres 19 m, cars
26.4 m); the instrumented rail is the right one. Wheel 13 carries the
measured tread of ``flat_0p3_03.dat`` (a 0.38 mm deep flat; see README.md
here for its source and licence), as a sampled outline r(θ) = R + deviation
with the flat's centre at θ = 0; its phase puts the flat on the rail 1.2 m
into the site. Deterministic: rerunning it gives the same file.

Every wheel carries its identity (docs/wheel-identity.md): the coach's European Vehicle
Number (check digit computed), the wheelset counted from the coach's end 1 and the side
relative to the coach. Coaches run end 1 leading except coach 6, which runs turned
(end 2 leading): its wheelsets count from the rear and its sides are not swapped.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SPEED = 160.0 / 3.6
CARS = 8
AXLES_IN_CAR = (3.7, 6.2, 22.7, 25.2)
CAR_LENGTH = 26.4
FLAT_WHEEL = 13
FLAT_FILE = HERE / "flat_0p3_03.dat"
FLAT_HITS_AT = 1.2
"""m into the site where the flat's centre first meets the rail."""
TURNED_CAR = 5
"""0-based: this coach runs end 2 leading."""


def vehicle_number(car: int) -> str:
    """A European Vehicle Number 61 80 2090 1cc-k (coach, Germany), with its Luhn check
    digit k, as a key chunk (spaces as '-')."""
    digits = f"618020901{car + 1:02d}"
    total = sum(
        sum(divmod(int(d) * (2 if i % 2 == 0 else 1), 10)) for i, d in enumerate(reversed(digits))
    )
    check = (10 - total % 10) % 10
    return f"{digits[:2]}-{digits[2:4]}-{digits[4:8]}-{digits[8:]}-{check}"


def measured_outline(path: Path) -> tuple[float, list[float], list[float]]:
    """Nominal radius and the outline (θ, r) of a trolley export, flat centred at θ = 0."""
    text = path.read_text(encoding="latin-1")
    rows = text.split("[MeasurementData]", 1)[1].strip().splitlines()[1:]
    pairs = [r.split("\t") for r in rows if r.strip()]
    s = np.array([float(p[0].replace(",", ".")) for p in pairs]) * 1e-3
    dev = np.array([float(p[1].replace(",", ".")) for p in pairs]) * 1e-6
    circumference = s[-1] - s[0] + (s[1] - s[0])
    radius = circumference / (2.0 * math.pi)
    theta = (s - s[np.argmin(dev)]) / radius
    theta = (theta + math.pi) % (2.0 * math.pi) - math.pi
    order = np.argsort(theta)
    return radius, theta[order].tolist(), (radius + dev[order]).tolist()


def main() -> None:
    radius_flat, theta, r = measured_outline(FLAT_FILE)
    wheels = []
    radii = (0.4585, 0.452, 0.445, 0.438)
    for car in range(CARS):
        for j, pos in enumerate(AXLES_IN_CAR):
            axle = car * len(AXLES_IN_CAR) + j
            x = car * CAR_LENGTH + pos - AXLES_IN_CAR[0]
            load = 52000.0 + 2000.0 * ((axle * 7) % 5)
            passage: dict[str, object] = {
                "passage_id": f"ic802-a{axle:02d}-r",
                "train_id": "ic802",
                "axle_index": axle,
                "side": "right",  # the instrumented rail, in the direction of travel
                "wheel": {
                    "vehicle_id": vehicle_number(car),
                    # end 1 leading: the front wheelset is 1 and vehicle sides are swapped
                    # with respect to travel; end 2 leading: counted from the rear, not swapped
                    "wheelset": len(AXLES_IN_CAR) - j if car == TURNED_CAR else j + 1,
                    "side": "right" if car == TURNED_CAR else "left",
                },
                "direction": "end2_leading" if car == TURNED_CAR else "end1_leading",
                "timestamp": 0.0,
                "speed": SPEED,
                "load": load,
                "mass": 600.0,
                "radius": radii[car % len(radii)],
            }
            if axle == FLAT_WHEEL:
                passage["radius"] = round(radius_flat, 6)
                passage["outline"] = {"kind": "sampled", "theta": theta, "radius": r}
                # φ = φ0 + x/R is 0 mod 2π (flat on the rail) at x = FLAT_HITS_AT
                passage["phase"] = (-FLAT_HITS_AT / radius_flat) % (2.0 * math.pi)
            wheels.append({"offset": round(x / SPEED, 6), "passage": passage})
    train = {
        "train_id": "ic802",
        "description": "8 cars, 32 axles at 160 km/h; axle 13 has a measured 0.38 mm wheel flat",
        "source": "axle 13 tread: flat_0p3_03.dat, supplementary material of 'A methodology of "
        "three-dimensional wheel flat modeling', Applied Sciences 14(13) 5956, 2024, "
        "CC BY 4.0",
        "wheels": wheels,
    }
    (HERE / "train_160kmh.json").write_text(json.dumps(train) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
