#!/usr/bin/env bash
# Check the system packages arenabench uses: the libraries off-screen rendering needs (EGL
# through Mesa, or OSMesa; required) and bubblewrap (bwrap), the sandbox of external pipelines
# (`eval --cmd`; optional: without it commands run unsandboxed, with a warning).
# Prints the exact install command when something is missing. Installs it itself only when
# allowed: running as root with apt-get, and ARENABENCH_INSTALL_SYSTEM_DEPS=1 or CI=true.
set -u
have_lib() { ldconfig -p 2>/dev/null | grep -q "$1"; }
egl_ok=0; osmesa_ok=0; bwrap_ok=0
if have_lib 'libEGL.so.1' && { have_lib 'libEGL_mesa.so.0' || have_lib 'libEGL_nvidia.so'; }; then
  egl_ok=1
fi
have_lib 'libOSMesa.so' && osmesa_ok=1
command -v bwrap >/dev/null 2>&1 && bwrap_ok=1
gl_ok=0
{ [ "$egl_ok" = 1 ] || [ "$osmesa_ok" = 1 ]; } && gl_ok=1
if [ "$gl_ok" = 1 ] && [ "$bwrap_ok" = 1 ]; then
  exit 0
fi
pkgs=""
if [ "$gl_ok" = 0 ]; then
  pkgs="libegl1 libegl-mesa0 libgl1-mesa-dri"
  echo "arenabench: off-screen OpenGL libraries missing (need libEGL.so.1 + libEGL_mesa.so.0, or libOSMesa)." >&2
fi
if [ "$bwrap_ok" = 0 ]; then
  pkgs="${pkgs:+$pkgs }bubblewrap"
  echo "arenabench: bubblewrap (bwrap) missing: external pipelines (--cmd) would run without a sandbox." >&2
fi
allowed=0
if [ "${ARENABENCH_INSTALL_SYSTEM_DEPS:-}" = 1 ] || [ "${CI:-}" = true ]; then allowed=1; fi
if [ "$allowed" = 1 ] && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
  echo "arenabench: installing $pkgs with apt-get" >&2
  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $pkgs >/dev/null && exit 0
  echo "arenabench: apt-get install failed" >&2
fi
echo "Install them with:  sudo apt-get install -y $pkgs" >&2
echo "(or set ARENABENCH_INSTALL_SYSTEM_DEPS=1 and run as root to let 'make' install them)" >&2
# only the rendering libraries are required
[ "$gl_ok" = 1 ] && exit 0
exit 1
