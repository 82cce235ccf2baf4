"""In-process pipelines that misbehave (``--pipeline hostile_callables:NAME``): each must fail
its image only."""

import os
import sys


def sys_exit(image):
    sys.exit(0)


def os_exit(image):
    os._exit(0)


def keyboard_interrupt(image):
    raise KeyboardInterrupt


def endless(image):
    while True:
        pass


def tuple_answer(image):
    """What ``map.py`` prints, as a tuple: no pipeline result."""
    return 2, 72000.0


def two_arguments(image, config):
    return {"count": 0, "area": 0.0}
