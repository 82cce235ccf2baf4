"""The toy detector, checking its working directory is its own.

Fails (exit 1) if the directory holds anything but the image's copy at start or if its
obstacles.txt changes while it sleeps; prints its working directory's device and inode so
the test can check they were all distinct (under bubblewrap every run sees it as /sandbox).
"""

import os
import sys
import time
from pathlib import Path

import cv2
from toy_arena import detect, obstacles_text

image_path = sys.argv[sys.argv.index("--image") + 1]
if os.listdir(".") != [os.path.basename(image_path)]:
    print(f"working directory holds more than the image: {os.listdir('.')}", file=sys.stderr)
    sys.exit(1)
text = obstacles_text(detect(cv2.imread(image_path)))
Path("obstacles.txt").write_text(text)
time.sleep(0.5)
if Path("obstacles.txt").read_text() != text:
    print("obstacles.txt was overwritten by someone else", file=sys.stderr)
    sys.exit(1)
st = os.stat(".")
print(f"cwd {os.getcwd()} {st.st_dev}:{st.st_ino}")
