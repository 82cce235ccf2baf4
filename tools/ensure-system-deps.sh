#!/usr/bin/env bash
# Check the system libraries that off-screen rendering needs (EGL through Mesa, or OSMesa).
# Also bubblewrap (bwrap), the sandbox of external pipelines (`eval --cmd`): installed with the
# opt-in below, else a hint (without it commands run unsandboxed, with a warning).
# Prints the exact install command when something is missing. Installs it itself only when
# allowed: running as root with apt-get, and ARENABENCH_INSTALL_SYSTEM_DEPS=1 or CI=true.
# With the same opt-in it also installs chromium (the headless browser tests/eval/reports/test_report_html.py
# renders the HTML report in); without it a missing chromium only skips those tests.
set -u
have_lib() { ldconfig -p 2>/dev/null | grep -q "$1"; }
have_chromium() { command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1; }
allowed=0
if [ "${ARENABENCH_INSTALL_SYSTEM_DEPS:-}" = 1 ] || [ "${CI:-}" = true ]; then allowed=1; fi
can_install=0
if [ "$allowed" = 1 ] && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
  can_install=1
fi
apt_updated=0
apt_install() {
  if [ "$apt_updated" = 0 ]; then apt-get update -qq && apt_updated=1 || return 1; fi
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$@" >/dev/null
}

if [ "$can_install" = 1 ] && ! have_chromium; then
  echo "arenabench: installing chromium with apt-get (for the HTML report test)" >&2
  apt_install chromium || echo "arenabench: apt-get install chromium failed" >&2
fi

if ! command -v bwrap >/dev/null 2>&1; then
  if [ "$can_install" = 1 ]; then
    echo "arenabench: installing bubblewrap with apt-get (the sandbox of external pipelines)" >&2
    apt_install bubblewrap || echo "arenabench: apt-get install bubblewrap failed" >&2
  else
    echo "arenabench: bubblewrap (bwrap) missing: external pipelines (--cmd) would run without a sandbox; install it with: sudo apt-get install -y bubblewrap" >&2
  fi
fi

egl_ok=0; osmesa_ok=0
if have_lib 'libEGL.so.1' && { have_lib 'libEGL_mesa.so.0' || have_lib 'libEGL_nvidia.so'; }; then
  egl_ok=1
fi
have_lib 'libOSMesa.so' && osmesa_ok=1
if [ "$egl_ok" = 1 ] || [ "$osmesa_ok" = 1 ]; then
  exit 0
fi
pkgs="libegl1 libegl-mesa0 libgl1-mesa-dri"
echo "arenabench: off-screen OpenGL libraries missing (need libEGL.so.1 + libEGL_mesa.so.0, or libOSMesa)." >&2
if [ "$can_install" = 1 ]; then
  echo "arenabench: installing $pkgs with apt-get" >&2
  apt_install $pkgs && exit 0
  echo "arenabench: apt-get install failed" >&2
fi
echo "Install them with:  sudo apt-get install -y $pkgs" >&2
echo "(or set ARENABENCH_INSTALL_SYSTEM_DEPS=1 and run as root to let 'make' install them)" >&2
exit 1
