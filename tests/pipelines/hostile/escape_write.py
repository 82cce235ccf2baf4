"""Tries to write outside its working directory: $TARGET, its own folder, the parent of its
working directory. Prints one line per attempt; answers 0 obstacles."""

import os

from common import answer

here = os.path.dirname(os.path.abspath(__file__))

for path in (os.environ["TARGET"], os.path.join(here, "escaped.txt"),
             os.path.join(os.getcwd(), "..", "escaped.txt")):
    try:
        with open(path, "w") as fh:
            fh.write("escaped")
        print(f"WROTE {path}")
    except OSError as exc:
        print(f"refused {path}: {exc.strerror}")
answer()
