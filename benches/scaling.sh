#!/usr/bin/env bash
# Scaling study: how map building (ray update and unscented OPDF merge, one
# core), simulation and ground truth grow with one thing varied at a time
# around the quickstart (tabletop, six viewpoints, 0.5° beams, 1 cm):
#
#   resolution 5 mm – 5 cm (with OctoMap's insertion of the same rays),
#   viewpoints 6 – 200, scene triangles 4 k – 1 M (a tessellated sphere on the
#   table), workspace volume 0.5 – 100 m³ (ground truth and a whole one-seed
#   `sigmap run`), beams per scan (angular step 2° – 0.125°).
#
#   bash benches/scaling.sh [OUT_DIR]     (default results/scaling; ~10 min)
#
# Writes OUT_DIR/scaling.csv (axis, x, measure, seconds, peak_mb: the peak
# resident memory of the whole process) and draws OUT_DIR/scaling.svg (time
# and peak memory against each axis, log-log). Map times are sigmap's own
# (`sigmap map`, one core); "simulate" is that command's wall time less them.
# Needs python3 and GNU time (/usr/bin/time); OctoMap's curve needs g++ and
# liboctomap-dev and is left out without them.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)
out=${1:-results/scaling}
mkdir -p "$out"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cargo build --release --quiet
cargo build --release --quiet --example scaling_chart
sigmap=target/release/sigmap
octomap=""
if command -v g++ >/dev/null && g++ -O2 -std=c++17 benches/octomap/insert.cpp -o "$work/insert" \
    -loctomap -loctomath 2>/dev/null; then
  octomap="$work/insert"
fi

csv="$work/scaling.csv"
echo "axis,x,measure,seconds,peak_mb" > "$csv"
# measure AXIS X MEASURE SECONDS PEAK_KB
record() { echo "$1,$2,$3,$4,$(awk -v k="$5" 'BEGIN{if (k == "NaN") print "NaN"; else printf "%.1f", k / 1024}')" >> "$csv"; }
# timed LOG CMD...: runs CMD with GNU time; leaves "wall peak_kb" in $work/time
timed() { local log=$1; shift; /usr/bin/time -f "%e %M" -o "$work/time" "$@" 2> "$log"; }
map_seconds() { sed -n 's/.* in \([0-9.]*\) s (.*/\1/p' "$1"; }

# map AXIS X EXPERIMENT [RESOLUTION]: both methods, one core; simulation
# time is the ray update's wall time less its map time.
map() {
  local axis=$1 x=$2 exp=$3 res=${4:-0.01}
  for method in ray_update unscented; do
    extra=()
    [[ -n $octomap && $axis == resolution && $method == ray_update ]] && extra=(--export-rays "$work/rays.bin")
    timed "$work/log" "$sigmap" map "$exp" --method "$method" --resolution "$res" --threads 1 \
      --out "$work/map.bt" "${extra[@]}"
    read -r wall peak < "$work/time"
    record "$axis" "$x" "map $method" "$(map_seconds "$work/log")" "$peak"
    if [[ $method == ray_update ]]; then
      # Its memory is the map command's: NaN, not drawn twice.
      record "$axis" "$x" simulate "$(awk -v w="$wall" -v m="$(map_seconds "$work/log")" 'BEGIN{print w - m}')" NaN
      beams=$(sed -n 's/.*; \([0-9]*\) beams in .*/\1/p' "$work/log")
    fi
  done
  if [[ -n $octomap && $axis == resolution ]]; then
    /usr/bin/time -f "%e %M" -o "$work/time" taskset -c 0 "$octomap" "$work/rays.bin" "$res" > "$work/olog"
    read -r wall peak < "$work/time"
    record "$axis" "$x" "OctoMap insert" "$(awk '{print $5}' "$work/olog")" "$peak"
  fi
}

inputs() { python3 benches/scaling/inputs.py "$repo" "$work/inputs" "$@"; }

for res in 0.005 0.01 0.02 0.05; do
  echo "resolution $res m" >&2
  map resolution "$res" "$(inputs resolution "$res")" "$res"
done
for n in 6 12 25 50 100 200; do
  echo "$n viewpoints" >&2
  map viewpoints "$n" "$(inputs viewpoints "$n")"
done
for t in 4000 16000 64000 256000 1000000; do
  echo "$t triangles" >&2
  map triangles "$t" "$(inputs triangles "$t")"
done
for v in 0.5 2 10 50 100; do
  echo "workspace $v m³" >&2
  exp=$(inputs workspace "$v")
  timed "$work/log" "$sigmap" ground-truth "$work/inputs/workspace_${v}_scene.toml" \
    --resolution 0.01 --out "$work/truth.bt"
  read -r wall peak < "$work/time"
  record workspace "$v" "ground truth" "$wall" "$peak"
  # The whole run (one seed, both methods): truth, observable mask, maps, scores.
  timed "$work/log" "$sigmap" run "$exp" --out "$work/run" --fresh --threads 1 --quiet
  read -r wall peak < "$work/time"
  record workspace "$v" "sigmap run" "$wall" "$peak"
  map workspace "$v" "$exp"
done
for step in 2 1 0.5 0.25 0.125; do
  echo "angular step $step°" >&2
  exp=$(inputs beams "$step")
  # x = beams per scan (six viewpoints): measured by the first map.
  map beams "$step" "$exp"
  sed -i "s/^beams,$step,/beams,$((beams / 6)),/" "$csv"
done

cp "$csv" "$out/scaling.csv"
target/release/examples/scaling_chart "$out/scaling.csv" "$out/scaling.svg"
echo "wrote $out/scaling.csv and $out/scaling.svg" >&2
