"""Print every site's wheel-flat diagnoses as they come (railtwin/<site>/diagnosis/<passage>)."""

import argparse
import contextlib

import common
import zenoh

from schemas.diagnosis import Diagnosis


def main(conf: zenoh.Config, site: str) -> None:
    with zenoh.open(conf) as session:
        key = f"railtwin/{site}/diagnosis/*"
        print(f"Declaring subscriber on {key}; CTRL-C to quit")
        for sample in session.declare_subscriber(key):
            d = Diagnosis.model_validate_json(sample.payload.to_bytes())  # any 1.x message
            wheel = d.wheel.id if d.wheel else "(wheel not identified)"
            flat = f"{d.flat.kind} {d.flat.length * 1e3:.0f} mm" if d.flat else "no flat"
            print(f">> {d.site_id} {d.passage_id} {wheel}: {d.verdict}, {flat}, peak "
                  f"{d.peak_force_measured / 1e3:.0f} kN measured")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(prog="watch_diagnoses", description=__doc__)
    common.add_config_arguments(parser)
    parser.add_argument("--site", default="*", help="a site's id, or * for every site")
    args = parser.parse_args()
    with contextlib.suppress(KeyboardInterrupt):
        main(common.get_config_from_args(args), args.site)
