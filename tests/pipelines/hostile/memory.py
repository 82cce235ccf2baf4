"""Allocates (and touches) $MB megabytes."""

import os

block = bytearray(int(os.environ.get("MB", "4096")) * 1024 * 1024)
block[:: 4096] = b"x" * len(block[:: 4096])
print("allocated", len(block))
