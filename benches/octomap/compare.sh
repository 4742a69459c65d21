#!/usr/bin/env bash
# Side-by-side insertion benchmark: sigmap vs OctoMap on the same rays, one core.
#
#   bash benches/octomap/compare.sh [EXPERIMENT] [RESOLUTIONS...]
#
# Needs g++ and Debian's liboctomap-dev (apt-get install liboctomap-dev).
# Exports the rays of EXPERIMENT (default experiments/octomap_bench.toml, about
# 700 000 rays, up to 3 m), inserts them with OctoMap's insertPointCloud (the
# program benches/octomap/insert.cpp) and with sigmap's ray update and OPDF
# merge (unscented; and `unscented+defaults`: the same experiment with its
# map settings left to sigmap's defaults, docs/math.md §5.7: pooled windows,
# surface samples, risk 0.5), at each resolution (default 0.02 0.05), and prints rays/s,
# the ratios to OctoMap, and bytes per leaf; then each sigmap method on two
# cores (--threads 2) against one, in ROUNDS (default 5) alternating rounds,
# with the median speed-up and its range, and a check that the map is the
# same file.
set -euo pipefail
cd "$(dirname "$0")/../.."
experiment=${1:-experiments/octomap_bench.toml}
shift || true
resolutions=${*:-0.02 0.05}
rounds=${ROUNDS:-5}
# shellcheck source=benches/octomap/setup.sh
source benches/octomap/setup.sh
per_leaf() { sed -n 's/.*(\([0-9.]*\) per leaf.*/\1/p'; }
# The experiment with the lines that pin the paper's map settings removed
# (its relative paths made absolute): sigmap's defaults.
defaults="$work/defaults.toml"
folder=$(cd "$(dirname "$experiment")" && pwd)
sed -e '/^beam_pooling = "off"/d' -e '/^interpolate_beams = "off"/d' -e '/^risk = "off"/d' \
  -e "s|\"\.\./|\"$folder/../|" -e "s|\"profiles/|\"$folder/profiles/|" "$experiment" > "$defaults"

printf '%-6s %-18s %12s %9s %14s\n' res method "M rays/s" "vs OctoMap" "bytes/leaf"
for res in $resolutions; do
  "$sigmap" map "$experiment" --method ray_update --resolution "$res" --threads 1 \
    --out "$work/ray.ot" --export-rays "$work/rays.bin" 2> "$work/ray.log"
  octomap=$(taskset -c 0 "$work/insert" "$work/rays.bin" "$res" "$work/octomap.ot")
  o_rate=$(awk '{print $7 / 1e6}' <<< "$octomap")
  o_leaf=$(awk '{print $13 / $11}' <<< "$octomap")
  printf '%-6s %-18s %12.3f %9s %14.1f\n' "$res" octomap "$o_rate" 1.00x "$o_leaf"
  for method in ray_update unscented; do
    taskset -c 0 "$sigmap" map "$experiment" --method "$method" --resolution "$res" --threads 1 \
      --out "$work/$method.ot" 2> "$work/$method.log"
    r=$(rate < "$work/$method.log")
    printf '%-6s %-18s %12.3f %8.2fx %14.1f\n' "$res" "$method" "$r" "$(awk -v a="$r" -v b="$o_rate" 'BEGIN{print a/b}')" \
      "$(per_leaf < "$work/$method.log")"
  done
  taskset -c 0 "$sigmap" map "$defaults" --method unscented --resolution "$res" --threads 1 \
    --out "$work/defaults.ot" 2> "$work/defaults.log"
  r=$(rate < "$work/defaults.log")
  printf '%-6s %-18s %12.3f %8.2fx %14.1f\n' "$res" unscented+defaults "$r" \
    "$(awk -v a="$r" -v b="$o_rate" 'BEGIN{print a/b}')" "$(per_leaf < "$work/defaults.log")"
  # Two cores against one: alternating rounds of the same map with one and
  # two threads (neither pinned), the median of the rounds' ratios; single
  # runs on a shared VM move by 10-30%.
  for method in ray_update unscented; do
    ratios=()
    for round in $(seq "$rounds"); do
      "$sigmap" map "$experiment" --method "$method" --resolution "$res" --threads 1 \
        --out "$work/$method.1.ot" 2> "$work/$method.1.log"
      "$sigmap" map "$experiment" --method "$method" --resolution "$res" --threads 2 \
        --out "$work/$method.2.ot" 2> "$work/$method.2.log"
      ratios+=("$(awk -v a="$(rate < "$work/$method.2.log")" -v b="$(rate < "$work/$method.1.log")" 'BEGIN{print a/b}')")
    done
    r2=$(rate < "$work/$method.2.log")
    same=$(cmp -s "$work/$method.ot" "$work/$method.2.ot" && echo "same map" || echo "MAP DIFFERS")
    spread=$(printf '%s\n' "${ratios[@]}" | sort -g | awk '{v[NR]=$1} END{printf "median %.2fx, %.2f-%.2f", (NR%2 ? v[(NR+1)/2] : (v[NR/2]+v[NR/2+1])/2), v[1], v[NR]}')
    printf '%-6s %-18s %12.3f %8.2fx  two cores over one: %s over %d rounds, %s\n' "$res" "$method" "$r2" \
      "$(awk -v a="$r2" -v b="$o_rate" 'BEGIN{print a/b}')" "$spread" "$rounds" "$same"
  done
  if command -v compare_octrees >/dev/null; then
    echo "  ray_update vs OctoMap: $(compare_octrees "$work/ray.ot" "$work/octomap.ot" 2>&1 | grep KLD)"
  fi
done
