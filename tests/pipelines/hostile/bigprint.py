"""Prints $MB megabytes to stdout (1 MiB at a time), then answers."""

import os
import sys

from common import answer

line = ("y" * 1023 + "\n") * 1024
for _ in range(int(os.environ.get("MB", "100"))):
    sys.stdout.write(line)
sys.stdout.write("the end\n")
sys.stdout.flush()
answer()
