"""ptrace-attaches its parent (the launcher, under --sandbox none), then sleeps: an attached
launcher would be stopped, and with it the run's timeout. Prints the attach result."""

import ctypes
import os
import time

PTRACE_ATTACH = 16

libc = ctypes.CDLL(None, use_errno=True)
result = libc.ptrace(PTRACE_ATTACH, os.getppid(), 0, 0)
print(f"attach {result} errno {ctypes.get_errno()}", flush=True)
time.sleep(60)
