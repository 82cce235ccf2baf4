"""The toy detector, checking its working directory is its own.

Fails (exit 1) if the directory is not empty at start or if its obstacles.txt changes while
it sleeps; prints its working directory so the test can check they were all distinct.
"""

import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cv2
from toy_arena import detect, obstacles_text

if os.listdir("."):
    print(f"working directory not empty: {os.listdir('.')}", file=sys.stderr)
    sys.exit(1)
image_path = sys.argv[sys.argv.index("--image") + 1]
text = obstacles_text(detect(cv2.imread(image_path)))
Path("obstacles.txt").write_text(text)
time.sleep(0.5)
if Path("obstacles.txt").read_text() != text:
    print("obstacles.txt was overwritten by someone else", file=sys.stderr)
    sys.exit(1)
print(f"cwd {os.getcwd()}")
