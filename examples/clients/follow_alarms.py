"""Follow the fleet's wheel alarms (railtwin/fleet/alarm/<vehicle_id>/<wheelset>/<side>)."""

import argparse
import contextlib
import json

import common
import zenoh

from schemas.messages import WheelRef


def main(conf: zenoh.Config, vehicle: str) -> None:
    with zenoh.open(conf) as session:
        for reply in session.get("railtwin/fleet/alarms", timeout=5.0):  # those open now
            if reply.ok is not None:
                print(f"open: {reply.ok.payload.to_string()}")
        key = f"railtwin/fleet/alarm/{vehicle}/*/*"
        print(f"Declaring subscriber on {key}; CTRL-C to quit")
        for sample in session.declare_subscriber(key):
            wheel = WheelRef.parse(str(sample.key_expr).removeprefix("railtwin/fleet/alarm/"))
            alarm = json.loads(sample.payload.to_bytes())
            print(f">> {wheel.id}: {alarm.get('severity')} {alarm.get('reason')} "
                  f"(evidence {alarm.get('evidence')})")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(prog="follow_alarms", description=__doc__)
    common.add_config_arguments(parser)
    parser.add_argument("--vehicle", default="*", help="one vehicle's id, or * for the fleet")
    args = parser.parse_args()
    with contextlib.suppress(KeyboardInterrupt):
        main(common.get_config_from_args(args), args.vehicle)
