"""Frames of isoline's NDJSON (gzip-compressed when the name ends in .gz), for the
scripts that read recordings beside a trajectory."""
import gzip
import json


def frames(path):
    """The records at `path`, one a non-empty line, in order."""
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt") as f:
        for line in f:
            if line.strip():
                yield json.loads(line)
