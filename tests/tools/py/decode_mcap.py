"""Decodes every message of an MCAP recording with the PyPI packages `mcap`,
`mcap-ros2-support` and `mcap-protobuf-support` (independent of ICKON's own
code; JSON channels with Python's json) and prints one JSON document: the
profile, messages per topic, per topic the schema, and what the Foxglove
view's channels hold (scene entities, transform children).

A message that does not decode makes the script exit with an error.
Usage: decode_mcap.py FILE
"""

import json
import sys
from collections import Counter

from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory
from mcap_ros2.decoder import DecoderFactory as Ros2DecoderFactory


def decode(factories, decoders, schema, channel, data):
    """One message decoded by the decoder its encoding calls for."""
    if channel.message_encoding == "json":
        return json.loads(data)
    decoder = decoders.get(channel.id)
    if decoder is None:
        for factory in factories:
            decoder = factory.decoder_for(channel.message_encoding, schema)
            if decoder is not None:
                break
        else:
            raise SystemExit(f"{channel.topic}: no decoder for {channel.message_encoding}")
        decoders[channel.id] = decoder
    return decoder(data)


def main(path):
    counts = Counter()
    schemas = {}
    encodings = set()
    view = {"scene_entities": [], "cell_entities": [], "tf_children": [], "metadata": {}}
    factories = [Ros2DecoderFactory(), ProtobufDecoderFactory()]
    decoders = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        header = reader.get_header()
        summary = reader.get_summary()
        for schema, channel, message in reader.iter_messages():
            decoded = decode(factories, decoders, schema, channel, message.data)
            if decoded is None:
                raise SystemExit(f"{channel.topic}: message {message.sequence} did not decode")
            counts[channel.topic] += 1
            encodings.add(channel.message_encoding)
            schemas[channel.topic] = schema.name if schema else None
            if "ickon_view" in channel.metadata:
                view["metadata"][channel.topic] = channel.metadata["ickon_view"]
            if channel.topic == "/site/scene":
                view["scene_entities"] = sorted({e.id for e in decoded.entities})
            elif channel.topic == "/site/cells":
                view["cell_entities"] = sorted(set(view["cell_entities"]) | {e.id for e in decoded.entities})
            elif channel.topic == "/tf":
                children = {t.child_frame_id for t in decoded.transforms}
                view["tf_children"] = sorted(set(view["tf_children"]) | children)
    stats = summary.statistics if summary else None
    print(
        json.dumps(
            {
                "profile": header.profile,
                "per_topic": counts,
                "schemas": schemas,
                "view": view,
                "message_encodings": sorted(encodings),
                "statistics_messages": stats.message_count if stats else None,
                "chunks": len(summary.chunk_indexes) if summary else 0,
                "compression": sorted({c.compression for c in summary.chunk_indexes}) if summary else [],
            }
        )
    )


if __name__ == "__main__":
    main(sys.argv[1])
