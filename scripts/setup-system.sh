#!/bin/sh
# The system packages kinodyn's demo and tests use, installed with apt-get where the user is root.
#
#   chromium chromium-driver   the viewer page in headless Chromium (browser tests, viewer benchmark)
#   libosmesa6 libegl1         offscreen OpenGL for video rendering (EGL on a GPU or Mesa, else OSMesa)
#   blender python3-numpy      reading kinodyn's BVH and glTF in Blender (round-trip tests)
#   nodejs npm                 the viewer's JavaScript bundle and the glTF validator (only when missing)
#   python3-venv               `python3 -m venv` on Debian (only when missing)
#
# Without root or apt-get it prints one line and changes nothing; the steps that need a missing
# package then skip, each saying why. A package apt cannot install is reported and skipped, and the
# others are still installed. Set KINODYN_SKIP_SYSTEM=1 to skip on purpose. Measured on Debian 12:
# chromium + chromium-driver ~20 s, libosmesa6 + libegl1 ~5 s, blender ~35 s, python3-numpy ~20 s.
# Safe to run again: installed packages are not touched.
set -u

PACKAGES="chromium chromium-driver libosmesa6 libegl1 blender python3-numpy"
say() { echo "setup-system: $*"; }

if [ "${KINODYN_SKIP_SYSTEM:-0}" = 1 ]; then
  say "skipped (KINODYN_SKIP_SYSTEM=1); tests needing Chromium, OSMesa/EGL or Blender will skip"
  exit 0
fi
if ! command -v apt-get >/dev/null 2>&1 || ! command -v dpkg-query >/dev/null 2>&1; then
  say "no apt-get here; install $PACKAGES yourself to run the browser, video and Blender steps"
  exit 0
fi
command -v node >/dev/null 2>&1 || PACKAGES="$PACKAGES nodejs"
command -v npm >/dev/null 2>&1 || PACKAGES="$PACKAGES npm"
python3 -c "import ensurepip" >/dev/null 2>&1 || PACKAGES="$PACKAGES python3-venv"

missing=""
for p in $PACKAGES; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing="$missing $p"
done
if [ -z "$missing" ]; then
  exit 0
fi
if [ "$(id -u)" != 0 ]; then
  say "not root; missing system packages:$missing (as root: sh scripts/setup-system.sh); the steps needing them will skip"
  exit 0
fi

export DEBIAN_FRONTEND=noninteractive
say "installing$missing"
if ! apt-get update -qq >/dev/null 2>&1; then
  say "apt-get update failed (no network or no package lists?); trying the installed lists"
fi
# shellcheck disable=SC2086  # one word per package
if ! apt-get install -y -qq --no-install-recommends $missing >/dev/null 2>&1; then
  failed=""
  for p in $missing; do  # one at a time: install what can be installed, report the rest
    apt-get install -y -qq --no-install-recommends "$p" >/dev/null 2>&1 || failed="$failed $p"
  done
  [ -n "$failed" ] && say "could not install:$failed (apt-get install$failed); the steps needing them will skip"
fi
exit 0
