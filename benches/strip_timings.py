"""Prints a plan's GeoJSON with every `timing*` key removed, keys sorted: two plans of one
input compare equal exactly when only their timings differ. Used by the identity-*.sh scripts."""
import json
import sys


def drop(o):
    if isinstance(o, dict):
        return {k: drop(v) for k, v in o.items() if "timing" not in k}
    if isinstance(o, list):
        return [drop(v) for v in o]
    return o


print(json.dumps(drop(json.load(open(sys.argv[1]))), sort_keys=True))
