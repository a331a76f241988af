#!/usr/bin/env bash
# Runs every test of the project (what .ci/run runs). Sets up first if needed (idempotent, fast when
# everything is installed and built).
#
#   bash scripts/test.sh               # all tests
#   bash scripts/test.sh -R Fiber      # extra arguments go to ctest (here: a name filter)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="${NY_BUILD_DIR:-$ROOT/build}"

bash "$ROOT/scripts/setup.sh" --no-run
ctest --test-dir "$BUILD" -j "$(nproc)" --output-on-failure "$@"
