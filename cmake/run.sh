#!/usr/bin/env bash
# The project's two commands (README):
#   bash cmake/run.sh demo          install dependencies, build, run the demo
#   bash cmake/run.sh test          install dependencies, build, run every test
#   bash cmake/run.sh test asan     the same under AddressSanitizer + UndefinedBehaviorSanitizer
set -euo pipefail
cd "$(dirname "$0")/.."
what=${1:-}
preset=${2:-dev}
bash cmake/setup-debian.sh
case "$what" in
  demo)
    cmake --preset release >/dev/null
    cmake --build --preset release --target dispmap
    ./build/release/examples/dispmap/dispmap demo
    ;;
  test)
    cmake --preset "$preset" >/dev/null
    cmake --build --preset "$preset"
    ctest --preset "$preset"
    ;;
  *)
    echo "usage: bash cmake/run.sh demo | test [dev|asan|release]" >&2
    exit 2
    ;;
esac
