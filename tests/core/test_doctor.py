"""`arenabench doctor`: real checks (real OpenCV, a real off-screen context in a subprocess)."""

import json

import pytest
from clirun import run_cli

from arenabench import doctor, glplatform


def _gl_available():
    try:
        glplatform.choose_platform()
    except glplatform.GLPlatformError:
        return False
    return True


@pytest.mark.integration
def test_checks_without_context_pass_here():
    report = doctor.run_checks(context=False)
    names = [c.name for c in report.checks]
    assert names[:5] == ["python", "numpy", "opencv", "opencv aruco", "pyrender"]
    by_name = {c.name: c for c in report.checks}
    assert by_name["opencv aruco"].ok, by_name["opencv aruco"].detail
    assert all(c.fix == "" for c in report.checks if c.ok)
    assert all(c.fix for c in report.checks if not c.ok)


@pytest.mark.skipif(not _gl_available(), reason="no EGL/OSMesa on this machine")
@pytest.mark.integration
def test_full_doctor_creates_a_context_and_exits_0(capsys):
    assert doctor.main(["--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["ok"] is True
    ctx = next(c for c in data["checks"] if c["name"] == "offscreen context")
    assert ctx["ok"] and ctx["detail"].split(":")[0] in ("egl", "osmesa")


@pytest.mark.integration
def test_broken_platform_fails_with_fix_and_exit_1(monkeypatch, capsys):
    # A platform name PyOpenGL does not know: the subprocess fails, the caller survives.
    monkeypatch.setenv("PYOPENGL_PLATFORM", "nosuchplatform")
    assert doctor.main([]) == 1
    out = capsys.readouterr().out
    assert "FAIL  offscreen context" in out
    assert "fix: " in out


def test_context_probe_timeout_is_reported():
    check = doctor.check_offscreen_context("egl", timeout=0.01)
    assert not check.ok and "no answer within" in check.detail and check.fix


def test_text_report_and_bad_option():
    report = doctor.DoctorReport([doctor.Check("a", True, "1.0"),
                                  doctor.Check("b", False, "missing", "pip install b")])
    text = report.to_text()
    assert "FAIL  b  missing" in text and "fix: pip install b" in text
    assert not report.ok
    assert doctor.main(["--timeout", "0"]) == 2


@pytest.mark.integration
def test_command_line_json_no_context():
    proc = run_cli("doctor", "--json", "--no-context")
    data = json.loads(proc.stdout)
    assert proc.returncode == (0 if data["ok"] else 1)
    assert {c["name"] for c in data["checks"]} >= {"python", "opencv", "opengl platform"}


@pytest.mark.integration
def test_sandbox_and_browser_checks_run_for_real(monkeypatch, tmp_path):
    import shutil

    from arenabench.eval.runs.sandbox import bwrap_problem

    check = doctor.check_sandbox()
    assert check.ok == (bwrap_problem() is None), check.detail
    assert check.required and (check.ok or "apt-get install -y bubblewrap" in check.fix)
    browser = doctor.check_browser()
    assert not browser.required
    assert browser.ok or browser.fix == doctor.BROWSER_FIX
    # no bwrap on PATH: FAIL with the command that installs it
    (tmp_path / "bin").mkdir()
    monkeypatch.setenv("PATH", str(tmp_path / "bin"))
    assert shutil.which("bwrap") is None
    missing = doctor.check_sandbox()
    assert not missing.ok and "apt-get install -y bubblewrap" in missing.fix
    no_browser = doctor.check_browser()
    assert not no_browser.ok and no_browser.fix == doctor.BROWSER_FIX
    report = doctor.DoctorReport([doctor.Check("a", True, "1"), no_browser])
    assert report.ok and "WARN  headless browser" in report.to_text()
