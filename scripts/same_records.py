#!/usr/bin/env python3
"""Whether two batch directories hold the same records: trials.jsonl byte for byte and
report.json as JSON, each with its timing aside (wall times differ run to run, nothing else
may). Prints the canonical trials.jsonl's md5 (the file without its "timing" objects).

    python3 scripts/same_records.py DIR_A DIR_B [TRIALS]

TRIALS: the number of records both must hold. Exit 0 equal, 1 different (saying where)."""
import hashlib
import json
import re
import sys


def canonical_trials(directory):
    with open(f"{directory}/trials.jsonl", "rb") as f:
        text = f.read()
    # Each record's "timing":{...} object holds only flat numbers, so [^}]* spans it.
    return re.sub(rb',"timing":\{[^}]*\}', b"", text)


def report(directory):
    with open(f"{directory}/report.json") as f:
        r = json.load(f)
    r.pop("timing", None)
    return r


def main():
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    a, b = sys.argv[1], sys.argv[2]
    ta, tb = canonical_trials(a), canonical_trials(b)
    if len(sys.argv) == 4:
        want = int(sys.argv[3])
        for d, t in ((a, ta), (b, tb)):
            records = t.count(b"\n")
            if records != want:
                sys.exit(f"{d}/trials.jsonl has {records} records, not {want}")
    if ta != tb:
        la, lb = ta.splitlines(), tb.splitlines()
        first = next((i for i, (x, y) in enumerate(zip(la, lb)) if x != y), min(len(la), len(lb)))
        sys.exit(f"trials.jsonl differs ({len(la)} vs {len(lb)} records; first difference at record {first})")
    if report(a) != report(b):
        sys.exit("report.json differs (timing aside)")
    md5 = hashlib.md5(ta).hexdigest()
    records = ta.count(b"\n")
    print(f"same records: {records} trials, canonical trials.jsonl md5 {md5}, report.json equal (timing aside)")


if __name__ == "__main__":
    main()
