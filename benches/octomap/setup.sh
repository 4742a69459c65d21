# Sourced by compare.sh and paired.sh, from the repository's root: a scratch
# directory `$work` (removed on exit), OctoMap's insertion program
# `$work/insert` (benches/octomap/insert.cpp, against Debian's
# liboctomap-dev), sigmap's release binary `$sigmap`, and `rate` (the M beams/s
# of a `sigmap map` report read on stdin).
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

g++ -O2 -std=c++17 benches/octomap/insert.cpp -o "$work/insert" -loctomap -loctomath
cargo build --release --quiet
sigmap=target/release/sigmap

rate() { sed -n 's/.*(\([0-9.]*\) M beams\/s).*/\1/p'; }
