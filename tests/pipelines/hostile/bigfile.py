"""Writes a $MB megabyte file into its working directory; with $NAME=obstacles.txt the file
is its (oversized) answer."""

import os

name = os.environ.get("NAME", "big.bin")
chunk = b"Obstacles: 1\n" + b"z" * (1024 * 1024 - 13)
with open(name, "wb") as fh:
    for _ in range(int(os.environ.get("MB", "200"))):
        fh.write(chunk)
print("wrote", name)
