#!/usr/bin/env bash
# Builds the ViSP yardstick of benches/vs_visp.sh: ViSP's model-based edge
# tracker over a pipetrack sequence (edge_tracker.cpp). Needs ViSP's
# development files (Debian: apt-get install libvisp-dev g++ pkg-config).
#
#   benches/visp/build.sh [OUT]     # OUT: the program's path (default target/visp_edge_tracker)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
out="${1:-$here/../../target/visp_edge_tracker}"
mkdir -p "$(dirname "$out")"
g++ -O3 -march=native -std=c++17 -Wall -Wextra "$here/edge_tracker.cpp" -o "$out" $(pkg-config --cflags --libs visp)
echo "built $out"
