"""Send one wheel passage to a site, then print the twin's answer (result or error)."""

import argparse
import json
import queue
import time

import common
import zenoh

from schemas.messages import Direction, WheelPassage, WheelRef, encoding_schema


def main(conf: zenoh.Config, site: str, wheel: WheelRef, direction: Direction) -> None:
    pid = f"{wheel.id.replace('/', '-')}-{int(time.time())}"
    passage = WheelPassage(passage_id=pid, train_id="example", axle_index=0, wheel=wheel,
                           direction=direction, side=wheel.rail_side(direction),
                           timestamp=time.time(), speed=30.0, load=98e3, mass=1000.0, radius=0.46)
    encoding = zenoh.Encoding.APPLICATION_JSON.with_schema(encoding_schema(WheelPassage))
    with zenoh.open(conf) as session:
        answers: queue.Queue[zenoh.Sample] = queue.Queue()
        for key in (f"railtwin/{site}/result/{pid}", f"railtwin/{site}/error"):
            session.declare_subscriber(key, answers.put)
        pub = session.declare_publisher(f"railtwin/{site}/passage", encoding=encoding)
        common.wait_for_subscriber(pub)  # else the put is lost
        print(f"Putting passage {pid} of wheel {wheel.id} on {pub.key_expr}")
        pub.put(passage.model_dump_json())
        answer = json.loads(answers.get(timeout=120).payload.to_bytes())  # result or error
        print(f">> {answer.get('summary') or answer.get('message')}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(prog="send_passage", description=__doc__)
    common.add_config_arguments(parser)
    parser.add_argument("--site", default="km12", help="the site's id (railtwin/<site>/...)")
    parser.add_argument("--wheel", type=WheelRef.parse, default="V1/1/left",
                        help="the wheel, <vehicle_id>/<wheelset>/<side>")
    parser.add_argument("--direction", choices=["end1_leading", "end2_leading"], default="end2_leading")
    args = parser.parse_args()
    main(common.get_config_from_args(args), args.site, args.wheel, args.direction)
