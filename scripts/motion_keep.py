#!/usr/bin/env python3
"""Slims one evaluation's metrics.json to what the Motion tables read, for keeping.

scripts/motion_bench.sh (KEEP=dir) stores every finished evaluation this way so that a
benchmark longer than one machine's life continues on the next, and so that the tables of
docs/RESULTS.md can be rebuilt from the kept files (docs/results/motion-shipped) with
scripts/motion_table.py and scripts/motion_headroom.py. Dropped: per-horizon and per-pair
breakdowns and the sweep; gzipped, a kept file is about 4% of the original; every mean, per-clip and per-method number
the tables use stays as written.

Standard library only. Usage: motion_keep.py SRC_METRICS_JSON DST (gzipped when DST ends in .gz)
"""
import gzip
import json
import os
import sys

DROP_METHOD = {"per_horizon"}
DROP_MOTION = {"per_frame_iou", "pairs"}
DROP_TOP = {"sweep"}


def slim_methods(methods):
    return [{k: v for k, v in m.items() if k not in DROP_METHOD} for m in methods]


def slim(report):
    out = {k: v for k, v in report.items() if k not in DROP_TOP}
    clips = []
    for c in report["clips"]:
        c = dict(c)
        c["methods"] = slim_methods(c["methods"])
        if c.get("motion"):
            c["motion"] = {k: v for k, v in c["motion"].items() if k not in DROP_MOTION}
        clips.append(c)
    out["clips"] = clips
    mean = dict(report["mean"])
    mean["methods"] = slim_methods(mean["methods"])
    out["mean"] = mean
    return out


def read_metrics(folder):
    """An evaluation's metrics.json, or the slimmed metrics.json.gz kept by motion_bench.sh
    (what the table scripts read)."""
    path = os.path.join(folder, "metrics.json")
    if os.path.exists(path):
        with open(path) as f:
            return json.load(f)
    with gzip.open(path + ".gz", "rt") as f:
        return json.load(f)


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    src, dst = sys.argv[1:]
    with open(src) as f:
        report = json.load(f)
    tmp = dst + ".tmp"
    text = json.dumps(slim(report), separators=(",", ":"))
    if dst.endswith(".gz"):
        # mtime 0: the same evaluation gives the same bytes, so git sees no change.
        with open(tmp, "wb") as f:
            f.write(gzip.compress(text.encode(), mtime=0))
    else:
        with open(tmp, "w") as f:
            f.write(text)
    os.replace(tmp, dst)


if __name__ == "__main__":
    main()
