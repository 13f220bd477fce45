#!/usr/bin/env bash
# Set up go2vlm on a fresh Debian/Ubuntu machine: the system libraries headless MuJoCo rendering
# needs (EGL, with OSMesa as the fallback), a virtualenv in .venv, and the package with extras.
#   scripts/setup.sh [EXTRAS]     EXTRAS: sim (the demo), all (default: everything incl. tests), ...
set -euo pipefail
cd "$(dirname "$0")/.."
extras="${1:-all}"
python="${PYTHON:-python3}"

sudo=""
[ "$(id -u)" = 0 ] || sudo="sudo"
apt_pkgs=(libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri libosmesa6 libglib2.0-0)
"$python" -c "import ensurepip, venv" 2>/dev/null || apt_pkgs+=(python3-venv)
# The test suite's WebRTC peer (the unmodified unitree-webrtc-connect, in a venv of its own) imports
# sounddevice, which needs the PortAudio library.
[ "$extras" = all ] && apt_pkgs+=(libportaudio2)
missing=()
for pkg in "${apt_pkgs[@]}"; do
  dpkg -s "$pkg" >/dev/null 2>&1 || missing+=("$pkg")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing system packages: ${missing[*]}"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv with $("$python" --version)"
  "$python" -m venv .venv
fi
.venv/bin/python -m pip install -q --upgrade pip
echo "setup: installing go2vlm[$extras] (the first time this takes a few minutes)"
.venv/bin/python -m pip install -q -c scripts/constraints.txt -e ".[$extras]"
echo "setup: done. Try: .venv/bin/go2vlm --help"
