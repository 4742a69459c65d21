#!/usr/bin/env bash
# Paired one-core rounds against OctoMap: how the ratios under issue 13's
# targets (docs/results.md, "Insertion speed against OctoMap") are measured.
#
#   bash benches/octomap/paired.sh [EXPERIMENT] [RESOLUTION]
#
# Needs g++ and Debian's liboctomap-dev. Exports the rays of EXPERIMENT
# (default experiments/octomap_bench.toml) once, then runs ROUNDS (default 12)
# rounds, each OctoMap's insertPointCloud (benches/octomap/insert.cpp) on the
# rays, then `sigmap map --threads 1` with the OPDF merge (unscented) and with
# the ray update, all pinned to cpu0, at RESOLUTION (default 0.05). Prints each
# round's rates and, per method, the mean of the rounds' ratios to OctoMap
# with its 95% t-interval: OctoMap's rate on a shared VM moves by a third from
# hour to hour, so only ratios of neighbouring runs compare.
set -euo pipefail
cd "$(dirname "$0")/../.."
experiment=${1:-experiments/octomap_bench.toml}
res=${2:-0.05}
rounds=${ROUNDS:-12}
if ! [[ $rounds =~ ^[0-9]+$ ]] || ((rounds < 2)); then
  echo "paired.sh: ROUNDS=$rounds: need a whole number of rounds, at least 2" >&2
  exit 2
fi
# shellcheck source=benches/octomap/setup.sh
source benches/octomap/setup.sh

"$sigmap" map "$experiment" --method ray_update --resolution "$res" --quiet \
  --out "$work/export.ot" --export-rays "$work/rays.bin"
printf '%-6s %16s %16s %16s\n' round "OctoMap M rays/s" "OPDF M beams/s" "ray M beams/s"
for round in $(seq "$rounds"); do
  octomap=$(taskset -c 0 "$work/insert" "$work/rays.bin" "$res" "$work/octomap.ot" | awk '{print $7 / 1e6}')
  for method in unscented ray_update; do
    taskset -c 0 "$sigmap" map "$experiment" --method "$method" --resolution "$res" --threads 1 \
      --out "$work/$method.ot" 2> "$work/$method.log"
  done
  printf '%-6s %16.3f %16.3f %16.3f\n' "$round" "$octomap" \
    "$(rate < "$work/unscented.log")" "$(rate < "$work/ray_update.log")"
done | tee "$work/rounds"
# Student's t quantile (0.975) for n - 1 degrees of freedom; 2.0 beyond 30.
awk -v res="$res" '
  BEGIN { split("12.706 4.303 3.182 2.776 2.571 2.447 2.365 2.306 2.262 2.228 2.201 2.179 2.160 2.145 2.131 2.120 2.110 2.101 2.093 2.086 2.080 2.074 2.069 2.064 2.060 2.056 2.052 2.048 2.045 2.042", t) }
  { for (m = 3; m <= 4; m++) { r = $m / $2; s[m] += r; ss[m] += r * r } n++ }
  END {
    q = (n - 1 <= 30) ? t[n - 1] : 2.0
    for (m = 3; m <= 4; m++) {
      mean = s[m] / n; sd = sqrt((ss[m] - n * mean * mean) / (n - 1)); h = q * sd / sqrt(n)
      printf "%s m, %d paired rounds, %-10s %.2fx OctoMap [%.2f, %.2f] (mean, 95%% t-interval)\n", res, n, (m == 3 ? "OPDF:" : "ray update:"), mean, mean - h, mean + h
    }
  }' < <(grep -E '^[0-9]+ ' "$work/rounds")
