#!/usr/bin/env bash
# The main job on its embedded default: set-up if needed, then the in-situ calibration demo.
set -euo pipefail
cd "$(dirname "$0")/.."
./tools/setup.sh
exec ./build/desktop-release/firmware/apps/playscope-demo "$@"
