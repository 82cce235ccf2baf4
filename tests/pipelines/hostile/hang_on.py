"""Answers at once, except for images whose sha256 is in $HANG (comma-separated, or "all"):
then it leaves a setsid daemon and a child, both sleeping 600 s with "$MARKER:child" on their
command line, and sleeps 600 s itself."""

import hashlib
import os
import subprocess
import time

from common import answer, daemonize, image_arg, sleeper

digest = hashlib.sha256(open(image_arg(), "rb").read()).hexdigest()
hang = os.environ.get("HANG", "")
if hang == "all" or digest in hang.split(","):
    marker = os.environ["MARKER"] + ":child"
    daemonize(marker)
    subprocess.Popen(sleeper(marker))
    time.sleep(600)
answer()
