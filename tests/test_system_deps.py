"""tools/ensure-system-deps.sh installs chromium (for the HTML report test) only when system
installs are allowed: root, apt-get, and ARENABENCH_INSTALL_SYSTEM_DEPS=1 or CI=true.

Runs the real script with a PATH of stand-ins (root ``id``, a logging ``apt-get``, an
``ldconfig`` that lists EGL) and no chromium on it."""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "tools" / "ensure-system-deps.sh"


@pytest.fixture
def stub_path(tmp_path):
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    log = tmp_path / "apt.log"
    stubs = {
        "id": "#!/bin/sh\necho 0\n",
        "apt-get": f'#!/bin/sh\necho "$*" >> "{log}"\n',
        "ldconfig": "#!/bin/sh\necho 'libEGL.so.1 libEGL_mesa.so.0'\n",
    }
    for name, text in stubs.items():
        (bin_dir / name).write_text(text)
        (bin_dir / name).chmod(0o755)
    (bin_dir / "grep").symlink_to(shutil.which("grep"))
    return bin_dir, log


def _run(bin_dir: Path, **env: str) -> subprocess.CompletedProcess:
    base = {k: v for k, v in os.environ.items()
            if k not in ("CI", "ARENABENCH_INSTALL_SYSTEM_DEPS")}
    return subprocess.run([shutil.which("bash"), str(SCRIPT)], env={**base, **env,
                          "PATH": str(bin_dir)}, capture_output=True, text=True, timeout=60)


@pytest.mark.parametrize("opt_in", [{"CI": "true"}, {"ARENABENCH_INSTALL_SYSTEM_DEPS": "1"}])
def test_chromium_is_installed_when_opted_in(stub_path, opt_in):
    bin_dir, log = stub_path
    proc = _run(bin_dir, **opt_in)
    assert proc.returncode == 0, proc.stderr
    assert "install -y -qq chromium" in log.read_text()


def test_nothing_is_installed_without_the_opt_in(stub_path):
    bin_dir, log = stub_path
    proc = _run(bin_dir)
    assert proc.returncode == 0, proc.stderr
    assert not log.exists()


def test_bubblewrap_is_installed_when_opted_in_else_a_hint(stub_path):
    bin_dir, log = stub_path
    hint = _run(bin_dir)
    assert hint.returncode == 0 and "sudo apt-get install -y bubblewrap" in hint.stderr
    assert not log.exists()
    proc = _run(bin_dir, CI="true")
    assert proc.returncode == 0, proc.stderr
    assert "install -y -qq bubblewrap" in log.read_text()
