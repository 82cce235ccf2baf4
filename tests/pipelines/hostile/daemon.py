"""Answers at once but leaves processes behind: a double-forked setsid daemon and a `setsid`
command, both holding stdout open, sleeping 600 s with $MARKER on their command line."""

import os
import subprocess

from common import answer, daemonize, sleeper

marker = os.environ["MARKER"]
daemonize(marker)
subprocess.Popen(["setsid", *sleeper(marker)])
answer()
print("answered", flush=True)
