"""Team folders a grade refuses before reading anything of them: a name that is not printable
(a newline would forge a line of grade's log, an escape sequence recolour a terminal), a link
to a system folder (a walk of / took three minutes before it was refused for its size) or to
a folder holding the submissions. The others are graded."""

from __future__ import annotations

import sys

import pytest
import toy_arena
from clirun import run_cli
from procs_limit import GRADE_ARGS

pytestmark = pytest.mark.integration

FAST_TEAM = ('from pathlib import Path\n'
             'Path("obstacles.txt").write_text("Aruco ID: [80, 85, 90, 95]\\nObstacles: 1\\n'
             'Area: 1.0\\n")\n')


def _subs(root, make_bad):
    (root / "plain").mkdir(parents=True)
    (root / "plain" / "map.py").write_text(FAST_TEAM)
    make_bad(root)
    return root


BAD = {
    "newline": lambda r: (r / "evil\nplain: graded (all passed)").mkdir(),
    "escape": lambda r: (r / "red\x1b[31m").mkdir(),
    "link-to-root": lambda r: (r / "root").symlink_to("/"),
    "link-to-etc": lambda r: (r / "etc").symlink_to("/etc"),
    "link-to-parent": lambda r: (r / "up").symlink_to(r.parent),
}


@pytest.mark.parametrize("kind", list(BAD))
def test_a_team_folder_that_cannot_be_a_submission_is_refused_in_one_line(tmp_path, kind):
    data = toy_arena.write_toy_dataset(tmp_path / "toy", n=2, seed=1)
    subs = _subs(tmp_path / "subs", BAD[kind])
    r = run_cli("grade", str(data), str(subs), "--out", str(tmp_path / "out"), "--cmd",
                f"{sys.executable} {{submission}}/map.py --image {{image}}", "--workers", "1",
                "--formats", "json", "--allow-guessable-seed", "--no-progress", *GRADE_ARGS)
    errors = [x for x in r.stdout.splitlines() if ": error: " in x]
    assert len(errors) == 1, r.stdout + r.stderr
    assert ("not printable" in errors[0] if kind in ("newline", "escape")
            else "link to" in errors[0]), errors
    assert "\x1b" not in r.stdout + r.stderr and not any(x.startswith("plain: graded (all")
                                              for x in r.stdout.splitlines())
    assert any(x.startswith("plain: graded (") for x in r.stdout.splitlines()), r.stdout
