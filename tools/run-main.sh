#!/usr/bin/env bash
# The main job on its embedded default: set-up if needed, then `playscope demo`: a simulated
# STRAS-like instrument from rendered video to flashed, verified tables and an HTML report.
# Extra arguments go to `playscope demo` (see `--help`), e.g. --out DIR, --device qemu.
set -euo pipefail
cd "$(dirname "$0")/.."
./tools/setup.sh --main
exec .venv/bin/playscope demo "$@"
