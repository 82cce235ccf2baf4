"""A pipeline that prints garbage and writes an obstacles.txt nobody can parse."""

import sys
from pathlib import Path

sys.stdout.buffer.write(b"\x00\x01\xff garbage \x1b[31m\n")
Path("obstacles.txt").write_text("the obstacles are: many\nsize = big\n")
