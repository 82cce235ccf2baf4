"""Looks for the dataset: ../gt/*.json next to the image and the working directory, every
parent folder of both, and the folder named in $TARGET. Prints what it found as one JSON line
(paths found, dataset-like names seen in any listing, its argv, environment and working
directory) and answers 0 obstacles."""

import glob
import json
import os
import sys

from common import answer, image_arg

image = os.path.abspath(image_arg())
found, listed = [], {}
starts = {os.path.dirname(image), os.getcwd(), os.environ.get("HOME", "/")}
for start in starts:
    d = start
    while True:
        try:
            names = os.listdir(d)
        except OSError as exc:
            names = [f"<{exc.strerror}>"]
        listed[d] = names
        found += [os.path.join(d, n) for n in names if n in ("gt", "manifest.jsonl")]
        found += glob.glob(os.path.join(d, "..", "gt", "*.json"))
        parent = os.path.dirname(d)
        if parent == d:
            break
        d = parent
target = os.environ.get("TARGET", "")
if target:
    for pattern in ("manifest.jsonl", "gt/*.json", "images/*"):
        found += glob.glob(os.path.join(target, pattern))
    try:
        listed[target] = os.listdir(target)
    except OSError as exc:
        listed[target] = [f"<{exc.strerror}>"]
suspicious = sorted({n for names in listed.values() for n in names} & {"gt", "manifest.jsonl",
                                                                        "images", "toy set"})
print(json.dumps({"found": found, "suspicious": suspicious, "target": listed.get(target),
                  "argv": sys.argv, "env": dict(os.environ), "cwd": os.getcwd(),
                  "cwd_files": os.listdir(".")}))
answer()
