#!/bin/sh
# One-line build of the SDFormat checker (needs: g++ pkg-config libsdformat-dev).
# Usage: tools/sdf_check/build.sh [OUTPUT]   (default: build/sdf_check/sdf_check)
set -e
out="${1:-build/sdf_check/sdf_check}"
mkdir -p "$(dirname "$out")"
g++ -O1 -o "$out" "$(dirname "$0")/sdf_check.cc" $(pkg-config --cflags --libs sdformat12)
