"""Run a command with CPU burners beside it: what a busy shared machine does to its waits.

    .venv/bin/python tools/with_burners.py --burners 2 -- .venv/bin/python -m pytest tests/...
    make test-busy TESTS="tests/eval/commands/test_interrupts.py" BURNERS=2

Each burner is a process spinning on the CPU at the command's own priority for as long as the
command runs; the burners end with it (and with this script, however it ends: each one checks
that its parent is alive). The exit status is the command's. With ``--repeat N`` the command
runs N times in a row and the first failure ends the loop (the status says which run failed).
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time

#: A burner: spin, and look up now and then whether the parent has gone.
BURNER = """\
import os, signal, sys
signal.signal(signal.SIGINT, signal.SIG_IGN)  # a Ctrl-C to the group is the command's
parent = int(sys.argv[1])
while True:
    for _ in range(200_000):
        pass
    if os.getppid() != parent:
        break
"""


def _parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="with_burners", description=__doc__.split("\n")[0])
    parser.add_argument("--burners", type=int, default=2, help="CPU burners (default 2)")
    parser.add_argument("--repeat", type=int, default=1, help="runs of the command (default 1)")
    parser.add_argument("command", nargs=argparse.REMAINDER, help="-- then the command")
    args = parser.parse_args(argv)
    if args.command[:1] == ["--"]:
        args.command = args.command[1:]
    if not args.command:
        parser.error("no command given (put it after --)")
    if args.burners < 0 or args.repeat < 1:
        parser.error("--burners must be >= 0 and --repeat >= 1")
    return args


def main(argv: list[str] | None = None) -> int:
    args = _parse(sys.argv[1:] if argv is None else argv)
    burners = [subprocess.Popen([sys.executable, "-c", BURNER, str(os.getpid())])
               for _ in range(args.burners)]
    print(f"with_burners: {args.burners} burner(s) running: {[b.pid for b in burners]}",
          file=sys.stderr, flush=True)
    rc = 0
    try:
        for run in range(1, args.repeat + 1):
            start = time.monotonic()
            rc = subprocess.call(args.command)
            print(f"with_burners: run {run} of {args.repeat} exited {rc} after "
                  f"{time.monotonic() - start:.0f} s; load {os.getloadavg()[0]:.1f}",
                  file=sys.stderr, flush=True)
            if rc != 0:
                break
    except KeyboardInterrupt:
        rc = 128 + signal.SIGINT
    finally:
        for burner in burners:
            burner.kill()
        for burner in burners:
            burner.wait()
    return rc


if __name__ == "__main__":
    sys.exit(main())
