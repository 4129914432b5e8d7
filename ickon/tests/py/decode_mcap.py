"""Decodes every message of an MCAP recording with the PyPI packages `mcap`
and `mcap-ros2-support` (independent of ICKON's own code) and prints one
JSON document: the profile, messages per topic, and per topic the schema.

A message that does not decode makes the script exit with an error.
Usage: decode_mcap.py FILE
"""

import json
import sys
from collections import Counter

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def main(path):
    counts = Counter()
    schemas = {}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        header = reader.get_header()
        summary = reader.get_summary()
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            if decoded is None:
                raise SystemExit(f"{channel.topic}: message {message.sequence} did not decode")
            counts[channel.topic] += 1
            schemas[channel.topic] = schema.name
    stats = summary.statistics if summary else None
    print(
        json.dumps(
            {
                "profile": header.profile,
                "per_topic": counts,
                "schemas": schemas,
                "statistics_messages": stats.message_count if stats else None,
                "chunks": len(summary.chunk_indexes) if summary else 0,
                "compression": sorted({c.compression for c in summary.chunk_indexes}) if summary else [],
            }
        )
    )


if __name__ == "__main__":
    main(sys.argv[1])
