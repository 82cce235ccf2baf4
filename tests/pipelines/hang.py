"""A pipeline that hangs: it starts a child that sleeps too, prints the child's pid, sleeps.

``--marker WORD`` is put on the child's command line, so a test can look for it in /proc
(the printed pid is the one in the sandbox's PID namespace).
"""

import subprocess
import sys
import time

marker = sys.argv[sys.argv.index("--marker") + 1] if "--marker" in sys.argv else "hang-child"
child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)", marker])
print(f"child-pid {child.pid}", flush=True)
time.sleep(600)
