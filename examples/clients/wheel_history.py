"""Ask the fleet service for one wheel's history and trend (railtwin/fleet/wheel/<wheel id>)."""

import argparse
import json
from datetime import UTC, datetime

import common
import zenoh

from schemas.messages import WheelRef


def main(conf: zenoh.Config, wheel: WheelRef, as_json: bool) -> None:
    with zenoh.open(conf) as session:
        key = f"railtwin/fleet/wheel/{wheel.id}"
        for reply in session.get(key, timeout=10.0):
            if reply.ok is None:
                print(f">> error: {reply.err.payload.to_string() if reply.err else reply}")
                continue
            doc = json.loads(reply.ok.payload.to_bytes())
            if as_json:
                print(json.dumps(doc, indent=2))
                continue
            print(f">> {doc['wheel_id']}: {len(doc['history'])} diagnoses")
            for e in doc["history"]:
                when = datetime.fromtimestamp(e["timestamp"], UTC).strftime("%Y-%m-%d %H:%M")
                flat = f"{e['flat']['length'] * 1e3:.0f} mm" if e.get("flat") else "no flat"
                print(f"   {when} {e['site_id']:>10} {e['passage_id']}: {e['verdict']}, {flat}")
            print(f"   trend: {json.dumps(doc.get('trend'))}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(prog="wheel_history", description=__doc__)
    common.add_config_arguments(parser)
    parser.add_argument("wheel", type=WheelRef.parse, help="<vehicle_id>/<wheelset>/<side>")
    parser.add_argument("--json", action="store_true", help="print the reply as it came")
    args = parser.parse_args()
    main(common.get_config_from_args(args), args.wheel, args.json)
