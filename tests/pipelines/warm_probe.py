"""Reports what a run can see of the way it was started (one JSON line on stdout), leaves
marks in every writable place it knows, and answers like the toy detector.

Used by tests/eval/runs/test_warm.py: a warm run finds cv2 already imported, no mark of an
earlier run,
``__name__ == "__main__"`` and the command line's ``sys.argv``. ``$PROBE_MODE`` = ``hang``,
``memory`` or ``forkbomb`` misbehaves instead, ``slow`` takes three seconds first, for the image
whose sha256 is ``$PROBE_BAD``.
"""

import hashlib
import json
import os
import sys
import time

preloaded = sorted(m for m in ("cv2", "numpy") if m in sys.modules)
image = sys.argv[sys.argv.index("--image") + 1]
digest = hashlib.sha256(open(image, "rb").read()).hexdigest()
if digest == os.environ.get("PROBE_BAD"):
    mode = os.environ.get("PROBE_MODE")
    if mode == "hang":
        time.sleep(600)
    elif mode == "memory":
        block = bytearray(1024 * 1024**2)
    elif mode == "slow":
        time.sleep(3)
    elif mode == "forkbomb":
        for _ in range(500):
            if os.fork() == 0:
                time.sleep(60)
                os._exit(0)

places = {os.environ.get("TMPDIR", "/tmp"), os.getcwd(), os.path.expanduser("~")}
if os.getcwd() == "/sandbox":  # the machine's own /tmp and /dev/shm only in a sandbox
    places |= {"/tmp", "/dev/shm"}
places = sorted(places)
marks = {place: os.path.exists(os.path.join(place, "warm-probe-mark")) for place in places}
for place in places:
    try:
        with open(os.path.join(place, "warm-probe-mark"), "w") as fh:
            fh.write(digest)
    except OSError:
        pass
os.remove(os.path.join(os.getcwd(), "warm-probe-mark"))
import cv2  # noqa: E402
from toy_arena import detect, obstacles_text  # noqa: E402

with open("obstacles.txt", "w") as fh:
    fh.write(obstacles_text(detect(cv2.imread(image))))
print(json.dumps({
    "preloaded": preloaded, "name": __name__, "argv": sys.argv, "marks": marks,
    "cwd": os.getcwd(), "cwd_files": sorted(os.listdir(".")), "path0": sys.path[1],
    "env": sorted(os.environ),
    "hidden": [os.listdir(p) if os.path.isdir(p) else None
               for p in ("/.arenabench-warm", "/.arenabench-cgroup",
                         "/sys/kernel/mm/transparent_hugepage")],
}))
