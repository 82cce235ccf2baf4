"""Forks up to 500 children that sleep 60 s (bounded, so a containment bug cannot hurt the
machine); an unhandled error when the system refuses a fork."""

import os
import time

for _ in range(500):
    pid = os.fork()
    if pid == 0:
        time.sleep(60)
        os._exit(0)
print("forked 500 children")
