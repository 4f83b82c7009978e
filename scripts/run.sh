#!/usr/bin/env bash
# One entry point for a fresh Debian 12 machine and a fresh clone: installs what is missing
# (OSMesa from Debian, a virtual environment, torch's CPU build, the package), then runs a task.
#
#   bash scripts/run.sh preview [preview options]   render a contact sheet of the built-in paintings
#   bash scripts/run.sh test [pytest options]       run the test suite on every core (pytest-xdist);
#                                                   add --runslow for the slow tests too (what .ci/run calls)
set -euo pipefail
cd "$(dirname "$0")/.."

# OSMesa (the default platform); EGL with Mesa's drivers and GL dispatch (PYOPENGL_PLATFORM=egl).
gl_packages="libosmesa6 libegl1 libgl1-mesa-dri libopengl0"
missing=""
for package in $gl_packages; do
  dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "ok installed" || missing="$missing $package"
done
if [ -n "$missing" ]; then
  sudo=""; [ "$(id -u)" -ne 0 ] && sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq $missing >/dev/null
fi
[ -x .venv/bin/python ] || python3 -m venv .venv
# torch first, pinned: 2.13.0 is the CPU build on these machines; an unpinned torch pulls CUDA (GBs).
# Then the package with the versions the suite was last checked with (scripts/constraints.txt).
# pip runs only when what it installs from changed since the last install that finished (the stamp:
# this script's pip lines, pyproject.toml, the constraints and the venv's Python), about 10 s saved.
torch_pin="torch==2.13.0"
stamp=".venv/sidar-install-stamp"
wanted="$(cat pyproject.toml scripts/constraints.txt <(grep "pip install" scripts/run.sh) | sha256sum | cut -c1-16) $torch_pin $(.venv/bin/python -V 2>&1)"
started=$(date +%s.%N)
if [ "$(cat "$stamp" 2>/dev/null)" != "$wanted" ]; then
  .venv/bin/python -m pip install -q "$torch_pin"
  .venv/bin/python -m pip install -q -c scripts/constraints.txt -e ".[test,ray,bench]"
  echo "$wanted" > "$stamp"
  echo "run.sh: installed in $(awk "BEGIN { printf \"%.1f\", $(date +%s.%N) - $started }") s" >&2
else
  echo "run.sh: installs up to date (pyproject.toml, scripts/constraints.txt unchanged), pip skipped" >&2
fi

task="${1:-}"; shift || true
case "$task" in
  preview) exec .venv/bin/python -m sidar_torch preview --out out/preview.png "$@" ;;
  test)    exec .venv/bin/python -m pytest -q -n auto "$@" ;;
  *)       echo "usage: bash scripts/run.sh preview|test [options]" >&2; exit 2 ;;
esac
