"""Connects to 127.0.0.1:$PORT. Answers (exit 0) only if the connection succeeded."""

import os
import socket
import sys

from common import answer

try:
    with socket.create_connection(("127.0.0.1", int(os.environ["PORT"])), timeout=3) as s:
        s.sendall(b"leak")
except OSError as exc:
    print(f"connect failed: {exc}", file=sys.stderr)
    sys.exit(1)
answer()
print("connected")
