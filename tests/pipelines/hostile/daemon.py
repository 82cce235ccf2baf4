"""Answers at once but leaves processes behind: a double-forked setsid daemon and a `setsid`
command, both holding stdout open, sleeping 600 s with $MARKER on their command line."""

import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import answer, daemonize, sleeper

marker = os.environ["MARKER"]
daemonize(marker)
subprocess.Popen(["setsid", *sleeper(marker)])
answer()
print("answered", flush=True)
