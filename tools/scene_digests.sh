#!/usr/bin/env bash
# Prints every built-in scene's final-state digest, one "NAME DIGEST" a line, for a
# refactor's proof that nothing moved: run it on the build before and after and compare
# (diff). Usage: tools/scene_digests.sh BUILD_DIR [STEPS]; without STEPS each scene runs
# its own length (minutes in all), with STEPS every scene stops after that many steps.
set -euo pipefail
build=${1:?usage: tools/scene_digests.sh BUILD_DIR [STEPS]}
steps=${2:-}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
for scene in $("$build/tearables" list | awk '{print $1}'); do
  args=(run "$scene" --out "$out/$scene" --quiet)
  if [ -n "$steps" ]; then args+=(--steps "$steps"); fi
  "$build/tearables" "${args[@]}" > /dev/null
  digest=$(sed -n 's/.*"digest": "\([0-9a-f]*\)".*/\1/p' "$out/$scene/summary.json")
  echo "$scene $digest"
done
