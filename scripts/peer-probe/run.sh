#!/usr/bin/env bash
# quiver's default kernel (AVX-512 and AVX2) beside tinybvh's BVH8_CPU and Embree 3's
# rtcIntersect1/rtcOccluded1 on the same triangles and rays, one thread: 1024² eye rays in
# 8x8 tiles, a shadow ray to the light and a cosine diffuse bounce from every eye hit.
# Needs the meshes (scripts/fetch-meshes.sh), g++, libembree-dev and the newest tiny_bvh.h
# in $TINYBVH_DIR (kept outside the repository). Rounds alternate the engines' processes.
set -euo pipefail
cd "$(dirname "$0")"
: "${TINYBVH_DIR:?the folder holding the newest tiny_bvh.h}"
mkdir -p data
python3 to_bin.py dragon ../../meshes/dragon_vrip.ply.gz data/dragon.bin
python3 to_bin.py nff ../../meshes/samurai_monastery.nff data/interior.bin
cargo build --release -q
g++ -O3 -march=native -std=c++20 -I"$TINYBVH_DIR" -o target/peers peers.cpp -lembree3
for s in interior dragon; do
    PROBE_REPS=1 PROBE_DUMP=data/$s.rays PROBE_SCENE=data/$s.bin target/release/peer-probe >/dev/null
done
for round in 1 2 3; do
    for s in interior dragon; do
        PROBE_SCENE=data/$s.bin target/release/peer-probe
        QUIVER_ISA=avx2 PROBE_SCENE=data/$s.bin target/release/peer-probe
        target/peers data/$s.bin data/$s.rays 5
    done
done
