"""A pipeline that hangs: it starts a child that sleeps too, prints the child's pid, sleeps."""

import subprocess
import sys
import time

child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])
print(f"child-pid {child.pid}", flush=True)
time.sleep(600)
