//! 4-wide BVHs: the binary tree collapsed so each node holds up to four child boxes, tested
//! together with SIMD. Two node formats: [`Bvh4Node`] (exact f32 boxes, 128 bytes) and
//! [`QBvh4Node`] (boxes quantized to 8 bits in a per-node frame, 64 bytes: one cache line).

use super::bvh2::leaf_order;
use super::order::{self, Shape, HOLE};
use crate::build::{BuildTree, NodeKind};
use crate::geometry::{Aabb, Primitive, Triangle};
use bytemuck::{Pod, Zeroable};

/// A child of a node in the collapsed tree.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Child {
    Empty,
    /// Index of a wide node.
    Inner(u32),
    /// A run of triangles in leaf order.
    Leaf {
        first: u32,
        count: u32,
    },
}

/// A node of the collapsed tree before it is encoded.
struct Wide {
    boxes: [Aabb; 4],
    kids: [Child; 4],
}

/// Collapses a binary tree into a 4-wide one in preorder. Each wide node starts from a binary
/// node's two children and repeatedly opens the inner child of largest surface area (the one a
/// ray is most likely to enter, so pulling its children up saves the most visits) until it has
/// four children or only leaves.
fn collapse(tree: &BuildTree) -> Vec<Wide> {
    let mut out = Vec::with_capacity(tree.nodes.len() / 3 + 1);
    let root = &tree.nodes[0];
    match root.kind {
        NodeKind::Inner { .. } => {
            collapse_node(tree, 0, &mut out);
        }
        NodeKind::Leaf { first, count } => {
            let mut w = Wide {
                boxes: [Aabb::EMPTY; 4],
                kids: [Child::Empty; 4],
            };
            if count > 0 {
                w.boxes[0] = root.bounds;
                w.kids[0] = Child::Leaf { first, count };
            }
            out.push(w);
        }
    }
    out
}

fn collapse_node(tree: &BuildTree, node: u32, out: &mut Vec<Wide>) -> u32 {
    let me = out.len() as u32;
    out.push(Wide {
        boxes: [Aabb::EMPTY; 4],
        kids: [Child::Empty; 4],
    });
    let is_inner = |n: u32| matches!(tree.nodes[n as usize].kind, NodeKind::Inner { .. });
    let kids_of = |n: u32| match tree.nodes[n as usize].kind {
        NodeKind::Inner { left, right } => (left, right),
        NodeKind::Leaf { .. } => unreachable!("only inner nodes are opened"),
    };
    let (l, r) = kids_of(node);
    let mut list = vec![l, r];
    while list.len() < 4 {
        let widest = list
            .iter()
            .enumerate()
            .filter(|(_, &n)| is_inner(n))
            .max_by(|(_, &a), (_, &b)| {
                let area = |n: u32| tree.nodes[n as usize].bounds.half_area();
                area(a).total_cmp(&area(b)).then(b.cmp(&a))
            })
            .map(|(i, _)| i);
        let Some(i) = widest else { break };
        let (a, b) = kids_of(list[i]);
        list.splice(i..=i, [a, b]);
    }
    for (slot, &n) in list.iter().enumerate() {
        let bn = &tree.nodes[n as usize];
        let kid = match bn.kind {
            NodeKind::Inner { .. } => Child::Inner(collapse_node(tree, n, out)),
            NodeKind::Leaf { first, count } => Child::Leaf { first, count },
        };
        out[me as usize].boxes[slot] = bn.bounds;
        out[me as usize].kids[slot] = kid;
    }
    me
}

/// Where a 4-wide BVH's nodes sit in memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Bvh4Mapping {
    /// Depth-first preorder.
    DepthFirst,
    /// Subtree blocks of one 4 KiB page, grown from each block root by area.
    Subtree,
}

/// Orders the collapsed tree and returns (slot table, position of every wide node).
fn arrange(wide: &[Wide], mapping: Bvh4Mapping, node_size: usize) -> (Vec<u32>, Vec<u32>) {
    let slots = match mapping {
        Bvh4Mapping::DepthFirst => (0..wide.len() as u32).collect(),
        Bvh4Mapping::Subtree => {
            let shape = Shape {
                kids: wide
                    .iter()
                    .map(|w| {
                        w.kids.map(|k| match k {
                            Child::Inner(i) => i,
                            _ => HOLE,
                        })
                    })
                    .collect(),
                area: wide
                    .iter()
                    .map(|w| {
                        w.boxes
                            .iter()
                            .fold(Aabb::EMPTY, |a, b| a.union(b))
                            .half_area()
                    })
                    .collect(),
            };
            order::subtree(&shape, 4096 / node_size)
        }
    };
    let pos = order::positions(&slots, wide.len());
    (slots, pos)
}

/// A 4-wide node with exact boxes: 128 bytes (two cache lines), 64-byte aligned.
///
/// The four child boxes are stored as six SIMD rows (min x, y, z, then max x, y, z; one lane
/// per child). Child `i`: `count[i] == 0` means an inner child at node index `child[i]`;
/// otherwise it is a leaf of `count[i] & !LEAF` triangles from `child[i]`. Unused slots are
/// empty leaves with an empty (inverted) box that no ray enters.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Bvh4Node {
    /// `[min_x, min_y, min_z, max_x, max_y, max_z]`, one lane per child.
    pub planes: [[f32; 4]; 6],
    /// Child node index (inner) or first triangle (leaf).
    pub child: [u32; 4],
    /// 0 for an inner child, [`Bvh4Node::LEAF`] | triangle count for a leaf.
    pub count: [u32; 4],
}

const _: () = assert!(std::mem::size_of::<Bvh4Node>() == 128);
const _: () = assert!(std::mem::align_of::<Bvh4Node>() == 64);

impl Bvh4Node {
    /// Flag bit marking a leaf child in [`Bvh4Node::count`].
    pub const LEAF: u32 = 1 << 31;

    fn encode(w: &Wide, pos: &[u32]) -> Self {
        let mut n = Bvh4Node::zeroed();
        for (i, (b, k)) in w.boxes.iter().zip(&w.kids).enumerate() {
            for a in 0..3 {
                n.planes[a][i] = b.min[a];
                n.planes[3 + a][i] = b.max[a];
            }
            (n.child[i], n.count[i]) = match *k {
                Child::Empty => (0, Self::LEAF),
                Child::Inner(j) => (pos[j as usize], 0),
                Child::Leaf { first, count } => (first, Self::LEAF | count),
            };
        }
        n
    }
}

/// A 4-wide BVH with exact f32 child boxes (over triangles unless `P` says otherwise).
///
/// ```
/// use quiver::layout::{Bvh4, Bvh4Mapping};
/// use quiver::build::{build, BuildConfig, Builder};
/// use quiver::{reference, layout::triangle_bounds};
/// use quiver_scenes::{scene::Scene};
/// let scene = Scene::load("tetra4").unwrap();
/// let tris = scene.triangles();
/// let tree = build(&triangle_bounds(&tris), &BuildConfig::default(), Builder::Binned);
/// let bvh = Bvh4::from_tree(&tree, &tris, Bvh4Mapping::DepthFirst);
/// let ray = scene.camera.ray(0.1, 0.0);
/// assert_eq!(bvh.closest_hit(&ray), reference::closest_hit(&tris, &ray));
/// ```
#[derive(Clone, Debug)]
pub struct Bvh4<P = Triangle> {
    /// Nodes; the root is node 0. Padding slots are nodes with four empty children.
    pub nodes: Vec<Bvh4Node>,
    /// Primitives in leaf order.
    pub prims: Vec<P>,
    /// For each entry of `tris`, its index in the input.
    pub prim_ids: Vec<u32>,
    /// Node order.
    pub mapping: Bvh4Mapping,
}

impl<P: Primitive> Bvh4<P> {
    /// Collapses and lays out a built binary tree.
    pub fn from_tree(tree: &BuildTree, prims: &[P], mapping: Bvh4Mapping) -> Self {
        let wide = collapse(tree);
        let (slots, pos) = arrange(&wide, mapping, std::mem::size_of::<Bvh4Node>());
        let empty = Wide {
            boxes: [Aabb::EMPTY; 4],
            kids: [Child::Empty; 4],
        };
        let nodes = slots
            .iter()
            .map(|&s| Bvh4Node::encode(if s == HOLE { &empty } else { &wide[s as usize] }, &pos))
            .collect();
        Bvh4 {
            nodes,
            prims: leaf_order(tree, prims),
            prim_ids: tree.prim_indices.clone(),
            mapping,
        }
    }

    /// Bytes of the node array.
    pub fn node_bytes(&self) -> usize {
        std::mem::size_of_val(self.nodes.as_slice())
    }

    /// Bytes of node and leaf data the traversal reads.
    pub fn bytes(&self) -> usize {
        self.node_bytes()
            + std::mem::size_of_val(self.prims.as_slice())
            + std::mem::size_of_val(self.prim_ids.as_slice())
    }
}

/// A 4-wide node in one 64-byte cache line: child boxes quantized to 8 bits per plane.
///
/// Coordinates are `origin + q · 2^exp` per axis, with `q` in 0..=255. Quantization rounds
/// outward and is checked in the same f32 arithmetic the traversal uses, so a decoded box
/// always contains the exact one: traversal may enter more boxes, never fewer. Child `i`:
/// `count[i] == 0` is an inner child at node `child[i]`, otherwise a leaf of `count[i]`
/// triangles from `child[i]`. Unused slots decode to an inverted box no ray enters, and carry
/// `child[i] == u32::MAX`.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct QBvh4Node {
    /// Lower corner of the node's frame.
    pub origin: [f32; 3],
    /// Per-axis step `2^exp` (`-126 <= exp <= 127`).
    pub exp: [i8; 3],
    /// Unused.
    pub pad: u8,
    /// `[min_x, min_y, min_z, max_x, max_y, max_z]` in steps from `origin`, one byte per child.
    pub q: [[u8; 4]; 6],
    /// Child node index (inner) or first triangle (leaf).
    pub child: [u32; 4],
    /// 0 for an inner child, else the leaf's triangle count.
    pub count: [u16; 4],
}

const _: () = assert!(std::mem::size_of::<QBvh4Node>() == 64);
const _: () = assert!(std::mem::align_of::<QBvh4Node>() == 64);

/// `2^e` for a normal exponent.
#[inline(always)]
pub(crate) fn pow2(e: i8) -> f32 {
    f32::from_bits(((e as i32 + 127) as u32) << 23)
}

/// Decodes one quantized coordinate exactly as the traversal does (a multiply, then an add).
#[inline(always)]
fn decode(origin: f32, step: f32, q: u8) -> f32 {
    origin + q as f32 * step
}

impl QBvh4Node {
    fn encode(w: &Wide, pos: &[u32]) -> Self {
        let frame = w.boxes.iter().fold(Aabb::EMPTY, |a, b| a.union(b));
        let mut n = QBvh4Node::zeroed();
        if frame.is_empty() {
            for i in 0..4 {
                (n.q[0][i], n.q[3][i]) = (255, 0);
                n.child[i] = u32::MAX;
            }
            return n;
        }
        n.origin = frame.min.into();
        for a in 0..3 {
            let (lo, hi) = (frame.min[a], frame.max[a]);
            // The smallest step whose 255th multiple reaches the frame's top.
            let mut e = ((hi - lo) / 255.0).log2().ceil().clamp(-126.0, 127.0) as i8;
            while e < 127 && decode(lo, pow2(e), 255) < hi {
                e += 1;
            }
            n.exp[a] = e;
        }
        for (i, (b, k)) in w.boxes.iter().zip(&w.kids).enumerate() {
            if *k == Child::Empty {
                for a in 0..3 {
                    (n.q[a][i], n.q[3 + a][i]) = (255, 0);
                }
                n.child[i] = u32::MAX;
                continue;
            }
            for a in 0..3 {
                let (o, step) = (n.origin[a], pow2(n.exp[a]));
                let mut qlo = ((b.min[a] - o) / step).floor().clamp(0.0, 255.0) as u8;
                while qlo > 0 && decode(o, step, qlo) > b.min[a] {
                    qlo -= 1;
                }
                let mut qhi = ((b.max[a] - o) / step).ceil().clamp(0.0, 255.0) as u8;
                while qhi < 255 && decode(o, step, qhi) < b.max[a] {
                    qhi += 1;
                }
                debug_assert!(decode(o, step, qlo) <= b.min[a] && decode(o, step, qhi) >= b.max[a]);
                (n.q[a][i], n.q[3 + a][i]) = (qlo, qhi);
            }
            (n.child[i], n.count[i]) = match *k {
                Child::Empty => unreachable!(),
                Child::Inner(j) => (pos[j as usize], 0),
                Child::Leaf { first, count } => {
                    let c = u16::try_from(count)
                        .expect("quantized BVH4 leaves hold at most 65535 triangles");
                    (first, c)
                }
            };
        }
        n
    }

    /// The decoded box of child `i` (conservative: contains the exact box).
    pub fn child_bounds(&self, i: usize) -> Aabb {
        let mut b = Aabb::EMPTY;
        for a in 0..3 {
            let (o, step) = (self.origin[a], pow2(self.exp[a]));
            b.min[a] = decode(o, step, self.q[a][i]);
            b.max[a] = decode(o, step, self.q[3 + a][i]);
        }
        b
    }
}

/// A 4-wide BVH with quantized 64-byte nodes, laid out depth-first.
///
/// ```
/// use quiver::layout::QBvh4;
/// use quiver::build::{build, BuildConfig, Builder};
/// use quiver::{reference, layout::triangle_bounds};
/// use quiver_scenes::{scene::Scene};
/// let scene = Scene::load("tetra4").unwrap();
/// let tris = scene.triangles();
/// let tree = build(&triangle_bounds(&tris), &BuildConfig::default(), Builder::Binned);
/// let bvh = QBvh4::from_tree(&tree, &tris);
/// let ray = scene.camera.ray(0.1, 0.0);
/// assert_eq!(bvh.closest_hit(&ray), reference::closest_hit(&tris, &ray));
/// ```
#[derive(Clone, Debug)]
pub struct QBvh4<P = Triangle> {
    /// Nodes in depth-first order; the root is node 0.
    pub nodes: Vec<QBvh4Node>,
    /// Primitives in leaf order.
    pub prims: Vec<P>,
    /// For each entry of `tris`, its index in the input.
    pub prim_ids: Vec<u32>,
}

impl<P: Primitive> QBvh4<P> {
    /// Collapses, quantizes and lays out a built binary tree.
    ///
    /// # Panics
    /// If a leaf holds more than 65535 triangles (a [`crate::build::BuildConfig::max_leaf_size`]
    /// above that).
    pub fn from_tree(tree: &BuildTree, prims: &[P]) -> Self {
        let wide = collapse(tree);
        let (slots, pos) = arrange(
            &wide,
            Bvh4Mapping::DepthFirst,
            std::mem::size_of::<QBvh4Node>(),
        );
        let nodes = slots
            .iter()
            .map(|&s| QBvh4Node::encode(&wide[s as usize], &pos))
            .collect();
        QBvh4 {
            nodes,
            prims: leaf_order(tree, prims),
            prim_ids: tree.prim_indices.clone(),
        }
    }

    /// Bytes of the node array.
    pub fn node_bytes(&self) -> usize {
        std::mem::size_of_val(self.nodes.as_slice())
    }

    /// Bytes of node and leaf data the traversal reads.
    pub fn bytes(&self) -> usize {
        self.node_bytes()
            + std::mem::size_of_val(self.prims.as_slice())
            + std::mem::size_of_val(self.prim_ids.as_slice())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3A;

    #[test]
    fn quantized_boxes_contain_the_exact_ones() {
        let mut rng = crate::rng::Rng::new(3);
        for scale in [1e-6f32, 1.0, 1e3, 1e7] {
            for _ in 0..200 {
                let mut boxes = [Aabb::EMPTY; 4];
                for b in boxes.iter_mut() {
                    let c = rng.in_box(Vec3A::splat(-scale), Vec3A::splat(scale))
                        + Vec3A::splat(scale * 3.0);
                    let e = rng.in_box(Vec3A::ZERO, Vec3A::splat(scale * 0.1));
                    *b = Aabb::new(c - e, c + e);
                }
                let w = Wide {
                    boxes,
                    kids: [Child::Leaf { first: 0, count: 1 }; 4],
                };
                let n = QBvh4Node::encode(&w, &[]);
                for (i, b) in boxes.iter().enumerate() {
                    assert!(
                        n.child_bounds(i).contains(b),
                        "scale {scale}: {b:?} not in {:?}",
                        n.child_bounds(i)
                    );
                }
            }
        }
    }

    #[test]
    fn collapse_keeps_every_leaf_once() {
        let bounds = crate::testing::soup_bounds(3000, 1);
        let tree = crate::build::build(&bounds, &Default::default(), crate::build::Builder::Binned);
        let wide = collapse(&tree);
        let mut covered = vec![false; tree.prim_indices.len()];
        for w in &wide {
            for k in &w.kids {
                if let Child::Leaf { first, count } = *k {
                    for c in &mut covered[first as usize..(first + count) as usize] {
                        assert!(!std::mem::replace(c, true));
                    }
                }
            }
        }
        assert!(covered.iter().all(|&c| c));
        // A wide node has fewer than four children only when none of them could be opened.
        for w in &wide {
            let used = w.kids.iter().filter(|k| **k != Child::Empty).count();
            let inner = w
                .kids
                .iter()
                .filter(|k| matches!(k, Child::Inner(_)))
                .count();
            assert!(
                used == 4 || inner == 0,
                "{used} children, {inner} of them inner"
            );
        }
    }
}
