#!/usr/bin/env bash
# Equal-time comparison of the methods (paper Figs. 3/7/9) on one scene: relMSE against a long
# path-traced reference, whose own error is estimated from its two independent halves.
# Usage: bench/equal_time.sh [SCENE.toml] [SIZE] [REFERENCE_SPP] [SECONDS...]
# Writes images and a table to bench/out/. Release build; uses every core.
set -euo pipefail
cd "$(dirname "$0")/.."
scene=${1:-assets/scenes/cornell_glossy_fog.toml}
size=${2:-128}
ref_spp=${3:-4096}
shift $(( $# < 3 ? $# : 3 ))
times=("${@:-20 60}")
out=bench/out
mkdir -p "$out"
cargo build --release --quiet
bin=target/release/beamlight
common=(--width "$size" --height "$size")
name=$(basename "$scene" .toml)

# Reference: two independent halves (different seeds), averaged by `compare`'s caller below.
for half in 1 2; do
  f="$out/${name}_ref${half}.exr"
  if [[ ! -f $f ]]; then
    "$bin" render "$scene" -o "$f" --method pt --spp $((ref_spp / 2)) --seed $((1000 + half)) "${common[@]}"
  fi
done
echo "reference halves against each other (the reference's own relMSE is about a quarter of this):"
"$bin" compare "$out/${name}_ref1.exr" "$out/${name}_ref2.exr" | grep relMSE

for t in ${times[*]}; do
  for method in pt vrl vrl-clamped vbl; do
    f="$out/${name}_${method}_${t}s.exr"
    "$bin" render "$scene" -o "$f" --method "$method" --time "$t" "${common[@]}" 2>&1 | grep done
    for half in 1 2; do
      printf '%-12s %4ss vs reference half %s: ' "$method" "$t" "$half"
      "$bin" compare "$f" "$out/${name}_ref${half}.exr" | grep relMSE
    done
  done
done
