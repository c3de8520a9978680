//! Saving a built [`Bvh`] of triangles to bytes and loading it back: [`Bvh::save`],
//! [`Bvh::to_bytes`], [`Bvh::load`], [`Bvh::from_bytes`], and the [`LoadError`] a file that is
//! not one quiver wrote gets instead of a BVH.
//!
//! The format (`docs/file-format.md` has the byte table): a 192-byte header (magic, format
//! version, endianness marker, layout and leaf format, frame, input counts, boxes, section
//! lengths), then five sections (nodes, leaf-order triangles, leaf-order input indices, SIMD
//! triangle groups, far groups), each the raw little-endian bytes of its `Pod` array padded
//! with zeros to a multiple of 64 bytes, then a 64-bit checksum of everything before it. Only
//! data that does not depend on the instruction set is stored: the kernels are chosen again
//! at load ([`Isa::detect`]), so a file written on an AVX-512 machine loads on any other.
//!
//! Why every check below: the kernels trust their node arrays (a child link is an index, a
//! leaf a range, the stack as deep as [`MAX_DEPTH`]), so a file is checked completely, in
//! one linear pass, before any query can see it. A loaded BVH is exactly the arrays quiver's
//! layout code would have built: a tree in the traversal's own view (each node reached once
//! from the root), in the canonical orders the refit relies on (depth-first layouts in
//! preorder, leaves' primitives and SIMD groups in the order the layout packs them), every
//! SIMD lane naming the input index the leaf order gives it.

use crate::builders::MAX_DEPTH;
use crate::bvh::AnyLayout;
use crate::frame::Frame;
use crate::geometry::{Aabb, Triangle};
use crate::isa::{Isa, Kernels};
use crate::layout::bvh2::Addressing;
use crate::layout::collapse::Wide;
use crate::layout::tri4::{groups as group_count, FarGroups};
use crate::layout::{
    Bvh2, Bvh2Mapping, Bvh2Node, Bvh4, Bvh4Mapping, Bvh4Node, Bvh8, Bvh8Node, Inputs, Layout,
    Node4, QBvh4Node, Tri4,
};
use crate::Bvh;
use bytemuck::Pod;
use glam::Vec3A;
use std::fmt;
use std::io::{self, Read, Write};

/// The first eight bytes of every file: a name, and a DOS end-of-file byte so the file does
/// not read as text.
const MAGIC: [u8; 8] = *b"QUIVBVH\x1a";

/// Written in the writer's byte order: read back as this value in the same order only.
pub(crate) const ENDIAN: u32 = 0x0102_0304;

/// The header's size; the sections follow it (a multiple of [`ALIGN`], so they start
/// aligned; bytes 136 on are reserved, zero).
const HEADER: usize = 192;

/// Every section starts and ends on this boundary (zero padding), so a file mapped into
/// memory has its arrays aligned for every node type (the largest alignment is 64).
const ALIGN: usize = 64;

/// The leaf format code of [`Triangle`] (fast triangle tests, [`Tri4`] groups of
/// `v0`, `e1`, `e2` rows in the wide layouts).
const LEAF_TRIANGLE: u8 = 1;

/// Bytes of one saved triangle: nine f32, the three corners (a [`Vec3A`] holds a fourth lane
/// nothing reads, which is not stored).
pub(crate) const TRIANGLE_BYTES: usize = 36;

/// The sections, in file order, with their element sizes where they do not depend on the
/// layout (the nodes' does).
const SECTIONS: [&str; 5] = ["nodes", "triangles", "ids", "groups", "far"];

/// Why bytes are not a BVH quiver can load: each variant names what was wrong, and where.
///
/// ```
/// use quiver_rt::{Bvh, LoadError, Triangle};
/// use quiver_rt::glam::Vec3A;
/// let bvh = Bvh::new(&[Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)]);
/// let mut bytes = bvh.to_bytes();
/// assert!(matches!(Bvh::from_bytes(&bytes[..100]), Err(LoadError::Truncated { .. })));
/// bytes[200] ^= 1;
/// assert!(matches!(Bvh::from_bytes(&bytes), Err(LoadError::Checksum { .. })));
/// assert!(matches!(Bvh::from_bytes(b"not a bvh file at all"), Err(LoadError::BadMagic)));
/// ```
#[derive(Debug)]
#[non_exhaustive]
pub enum LoadError {
    /// Reading failed (other than by ending early, which is [`LoadError::Truncated`]).
    Io(io::Error),
    /// The first eight bytes are not quiver's magic: not a saved BVH.
    BadMagic,
    /// A format version this quiver does not read (see [`Bvh::FORMAT_VERSION`], and
    /// [`World::FORMAT_VERSION`](crate::World::FORMAT_VERSION) for world files).
    UnsupportedVersion {
        /// The file's version.
        found: u32,
        /// The newest version this quiver reads.
        supported: u32,
    },
    /// Written on a machine of the other byte order.
    WrongEndianness,
    /// A header field holds a value no writer writes (`field` names it).
    BadHeader {
        /// The field.
        field: &'static str,
        /// Its value.
        value: u64,
    },
    /// A section's length times its element size, or the sum of the sections, overflows.
    LengthOverflow {
        /// The section.
        section: &'static str,
    },
    /// The bytes end before the section (or header, or checksum) does.
    Truncated {
        /// The part cut short: `header`, a section's name, or `checksum`.
        section: &'static str,
        /// Bytes needed up to its end.
        need: u64,
        /// Bytes present.
        have: u64,
    },
    /// Bytes after the checksum ([`Bvh::from_bytes`] takes exactly one file).
    TrailingBytes {
        /// How many.
        extra: u64,
    },
    /// The checksum over the file does not match the one stored: the bytes changed since
    /// they were written.
    Checksum {
        /// The stored checksum.
        stored: u64,
        /// The checksum of the bytes present.
        computed: u64,
    },
    /// The zero padding after a section is not zero.
    Padding {
        /// The section.
        section: &'static str,
    },
    /// A section's length does not fit the layout (`why` says how).
    SectionLength {
        /// The section.
        section: &'static str,
        /// Its length in elements.
        len: u64,
        /// What the layout needs.
        why: &'static str,
    },
    /// A child link names no node.
    ChildOutOfRange {
        /// The parent.
        node: usize,
        /// The link (an index, or for a compact block node its height).
        child: u64,
    },
    /// A node is reached twice from the root: the links form a cycle or share a subtree.
    NotATree {
        /// The node reached again.
        node: usize,
    },
    /// A node lies deeper than the traversal kernels' stacks allow.
    TooDeep {
        /// Its depth (the root's is 0).
        depth: usize,
        /// The deepest allowed ([`MAX_DEPTH`]).
        max: usize,
    },
    /// A depth-first layout's node is not where preorder puts it.
    NotPreorder {
        /// The node.
        node: usize,
        /// Where preorder puts it.
        expected: usize,
    },
    /// A box holds a NaN or an infinity (other than an empty box's), or a quantized node's
    /// frame is not finite.
    NonFiniteBox {
        /// The node.
        node: usize,
    },
    /// A leaf's range is not the next one in leaf order, or runs past its array.
    PrimitiveOutOfRange {
        /// The node holding the leaf.
        node: usize,
        /// The leaf's first primitive (binary layouts) or group (wide layouts).
        first: u64,
        /// Its primitives.
        count: u64,
        /// Where leaf order puts its first.
        expected: u64,
        /// The array's length.
        len: u64,
    },
    /// The leaves do not cover their array exactly.
    Coverage {
        /// The section.
        section: &'static str,
        /// Elements the leaves cover.
        covered: u64,
        /// The section's length.
        len: u64,
    },
    /// A wide node's slot is neither an inner child (count 0) nor a leaf (the leaf flag set):
    /// the kernels would read it as a child, a refit as a leaf.
    SlotKind {
        /// The node.
        node: usize,
        /// The slot.
        slot: usize,
        /// Its count field.
        count: u32,
    },
    /// A SIMD group's lane does not name the input index leaf order gives it (or an unused
    /// lane is not the all-NaN lane no ray hits).
    GroupLane {
        /// The group.
        group: usize,
        /// The lane.
        lane: usize,
    },
    /// An input index past the number of inputs.
    IdOutOfRange {
        /// Its position in the ids section.
        at: usize,
        /// The index.
        id: u32,
        /// The number of inputs.
        len: u64,
    },
    /// The far-group list is not strictly ascending or names no group.
    FarGroup {
        /// The position in the list.
        at: usize,
    },
    /// A node no link reaches is not the padding the layout leaves.
    Unreached {
        /// The node.
        node: usize,
    },
    /// A world file's geometry holds a BVH that does not load (`error` says why).
    InGeometry {
        /// The geometry.
        geometry: usize,
        /// What is wrong with its BVH.
        error: Box<LoadError>,
    },
    /// A world file's geometry stores another number of triangles than its BVH was built
    /// over.
    GeometryLength {
        /// The geometry.
        geometry: usize,
        /// Triangles stored.
        triangles: u64,
        /// Triangles its BVH was built over.
        inputs: u64,
    },
    /// A world file's instances do not make a world: one names no geometry, or its transform
    /// is not finite or not invertible, or there are too many.
    World(crate::world::WorldError),
}

impl fmt::Display for LoadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use LoadError::*;
        match self {
            Io(e) => write!(f, "reading the BVH file: {e}"),
            BadMagic => f.write_str("not a saved quiver BVH (wrong magic bytes)"),
            UnsupportedVersion { found, supported } => write!(
                f,
                "format version {found}; this quiver reads versions 1 to {supported}"
            ),
            WrongEndianness => f.write_str("written on a machine of the other byte order"),
            BadHeader { field, value } => write!(f, "header field {field} holds {value}"),
            LengthOverflow { section } => write!(f, "the {section} section's length overflows"),
            Truncated {
                section,
                need,
                have,
            } => write!(
                f,
                "truncated in the {section}: {need} bytes needed, {have} present"
            ),
            TrailingBytes { extra } => write!(f, "{extra} bytes after the checksum"),
            Checksum { stored, computed } => write!(
                f,
                "checksum mismatch: stored {stored:#018x}, bytes give {computed:#018x}"
            ),
            Padding { section } => write!(f, "the padding after the {section} is not zero"),
            SectionLength { section, len, why } => {
                write!(f, "the {section} section holds {len}: {why}")
            }
            ChildOutOfRange { node, child } => {
                write!(f, "node {node} links to {child}, which is no node")
            }
            NotATree { node } => write!(
                f,
                "node {node} is reached twice from the root (a cycle or a shared subtree)"
            ),
            TooDeep { depth, max } => write!(
                f,
                "a node at depth {depth}, past the traversal stacks' {max}"
            ),
            NotPreorder { node, expected } => write!(
                f,
                "node {node} is not in depth-first preorder (expected at {expected})"
            ),
            NonFiniteBox { node } => write!(f, "node {node} has a non-finite box"),
            PrimitiveOutOfRange {
                node,
                first,
                count,
                expected,
                len,
            } => write!(
                f,
                "a leaf of node {node} covers {first}..{first}+{count}; leaf order puts it at \
                 {expected}, of {len}"
            ),
            Coverage {
                section,
                covered,
                len,
            } => write!(f, "the leaves cover {covered} of the {len} {section}"),
            SlotKind { node, slot, count } => write!(
                f,
                "slot {slot} of node {node} has count {count:#x}: neither an inner child (0) \
                 nor a leaf (the leaf flag set)"
            ),
            GroupLane { group, lane } => write!(
                f,
                "lane {lane} of group {group} is not the triangle leaf order gives it"
            ),
            IdOutOfRange { at, id, len } => {
                write!(f, "input index {id} at {at}, of {len} inputs")
            }
            FarGroup { at } => write!(f, "far-group entry {at} is not ascending or names no group"),
            Unreached { node } => {
                write!(f, "node {node} is reached by no link and is not padding")
            }
            InGeometry { geometry, error } => write!(f, "geometry {geometry}'s BVH: {error}"),
            GeometryLength {
                geometry,
                triangles,
                inputs,
            } => write!(
                f,
                "geometry {geometry} stores {triangles} triangles, its BVH was built over {inputs}"
            ),
            World(e) => write!(f, "the world's instances: {e}"),
        }
    }
}

impl std::error::Error for LoadError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            LoadError::Io(e) => Some(e),
            _ => None,
        }
    }
}

impl From<io::Error> for LoadError {
    fn from(e: io::Error) -> Self {
        LoadError::Io(e)
    }
}

// ---------------------------------------------------------------------------------------
// The checksum.

/// FNV-1a's 64-bit offset basis and prime.
const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;

/// Bytes per checksum block: blocks are hashed in parallel, then their hashes in order.
const BLOCK: usize = 1 << 20;

/// One FNV-1a step over a 64-bit word. `(s ^ w) * odd` is a bijection of `s` for a fixed
/// `w` and of `w` for a fixed `s`, so changing any one word of a stream (any single bit or
/// byte flip) always changes the final state: single-word corruption is always detected.
#[inline(always)]
fn fnv(s: u64, w: u64) -> u64 {
    (s ^ w).wrapping_mul(FNV_PRIME)
}

/// FNV-1a-64 over the little-endian 64-bit words of `block` (zero-padded to a whole word),
/// in four interleaved streams (word `i` to stream `i % 4`: four multiplications in flight,
/// not one chain), folded in stream order.
fn block_hash(block: &[u8]) -> u64 {
    let mut s = streams();
    let whole = block.len() / 32 * 32;
    quads(&mut s, &block[..whole]);
    tail(&mut s, &block[whole..]);
    fold_streams(&s)
}

/// The four streams' starting states.
fn streams() -> [u64; 4] {
    std::array::from_fn(|l| FNV_OFFSET ^ l as u64)
}

/// Steps the streams over `bytes`, a whole number of 32-byte quads starting on a quad
/// boundary of the block (word `i` of a quad to stream `i`).
#[inline]
fn quads(s: &mut [u64; 4], bytes: &[u8]) {
    for q in bytes.chunks_exact(32) {
        for (l, s) in s.iter_mut().enumerate() {
            let w = u64::from_le_bytes(q[8 * l..8 * l + 8].try_into().expect("8 bytes"));
            *s = fnv(*s, w);
        }
    }
}

/// Steps the streams over a block's last bytes, fewer than a quad: word `i` to stream `i`,
/// the last word zero-padded.
fn tail(s: &mut [u64; 4], bytes: &[u8]) {
    for (i, w) in bytes.chunks(8).enumerate() {
        let mut b = [0u8; 8];
        b[..w.len()].copy_from_slice(w);
        s[i] = fnv(s[i], u64::from_le_bytes(b));
    }
}

fn fold_streams(s: &[u64; 4]) -> u64 {
    s.iter().fold(FNV_OFFSET, |h, &x| fnv(h, x))
}

/// [`checksum`] over bytes that arrive in pieces of any size: the same value as `checksum` of
/// all of them at once, computed while each piece is still in cache.
struct StreamSum {
    s: [u64; 4],
    /// Bytes of the current block stepped into `s` (whole quads).
    in_block: usize,
    /// The start of a quad not yet complete.
    quad: [u8; 32],
    quad_len: usize,
    /// The hashes of the blocks done, folded in order.
    h: u64,
    len: usize,
}

impl StreamSum {
    fn new() -> Self {
        StreamSum {
            s: streams(),
            in_block: 0,
            quad: [0; 32],
            quad_len: 0,
            h: FNV_OFFSET,
            len: 0,
        }
    }

    fn put(&mut self, mut bytes: &[u8]) {
        self.len += bytes.len();
        if self.quad_len > 0 {
            let take = (32 - self.quad_len).min(bytes.len());
            self.quad[self.quad_len..self.quad_len + take].copy_from_slice(&bytes[..take]);
            self.quad_len += take;
            bytes = &bytes[take..];
            if self.quad_len < 32 {
                return;
            }
            let q = self.quad;
            self.put_quads(&q);
            self.quad_len = 0;
        }
        let whole = bytes.len() / 32 * 32;
        self.put_quads(&bytes[..whole]);
        let rest = &bytes[whole..];
        self.quad[..rest.len()].copy_from_slice(rest);
        self.quad_len = rest.len();
    }

    /// Whole quads, split at block ends.
    fn put_quads(&mut self, mut bytes: &[u8]) {
        while !bytes.is_empty() {
            let take = (BLOCK - self.in_block).min(bytes.len());
            quads(&mut self.s, &bytes[..take]);
            self.in_block += take;
            bytes = &bytes[take..];
            if self.in_block == BLOCK {
                self.h = fnv(self.h, fold_streams(&self.s));
                self.s = streams();
                self.in_block = 0;
            }
        }
    }

    fn finish(mut self) -> u64 {
        // A quad never straddles a block end (blocks are whole quads), so the last partial
        // quad is its block's tail.
        if self.quad_len > 0 {
            let q = self.quad;
            tail(&mut self.s, &q[..self.quad_len]);
        }
        if self.in_block > 0 || self.quad_len > 0 {
            self.h = fnv(self.h, fold_streams(&self.s));
        }
        fnv(self.h, self.len as u64)
    }
}

/// The file checksum of `data` (everything before the stored checksum): FNV-1a-64 over the
/// hashes of its 1 MiB blocks in order ([`block_hash`]), then its length.
pub(crate) fn checksum(data: &[u8]) -> u64 {
    use rayon::prelude::*;
    let blocks: Vec<u64> = data.par_chunks(BLOCK).map(block_hash).collect();
    fold_blocks(&blocks, data.len())
}

fn fold_blocks(blocks: &[u64], len: usize) -> u64 {
    let h = blocks.iter().fold(FNV_OFFSET, |h, &b| fnv(h, b));
    fnv(h, len as u64)
}

/// A writer that hashes what passes through it, block by block, as [`checksum`] does.
pub(crate) struct Hashing<'w, W: ?Sized> {
    w: &'w mut W,
    block: Vec<u8>,
    blocks: Vec<u64>,
    len: usize,
}

impl<'w, W: Write + ?Sized> Hashing<'w, W> {
    /// Hashes what is written to `w`.
    pub(crate) fn new(w: &'w mut W) -> Self {
        Hashing {
            w,
            block: Vec::with_capacity(BLOCK),
            blocks: Vec::new(),
            len: 0,
        }
    }

    pub(crate) fn put(&mut self, mut bytes: &[u8]) -> io::Result<()> {
        self.w.write_all(bytes)?;
        self.len += bytes.len();
        while !bytes.is_empty() {
            let take = (BLOCK - self.block.len()).min(bytes.len());
            self.block.extend_from_slice(&bytes[..take]);
            bytes = &bytes[take..];
            if self.block.len() == BLOCK {
                self.blocks.push(block_hash(&self.block));
                self.block.clear();
            }
        }
        Ok(())
    }

    /// Puts each triangle's nine coordinates, little-endian ([`triangle_bytes`]), a few
    /// large writes at a time.
    pub(crate) fn put_triangles(&mut self, tris: &[Triangle]) -> io::Result<()> {
        let mut bytes = Vec::with_capacity(tris.len().min(1 << 16) * TRIANGLE_BYTES);
        for chunk in tris.chunks(1 << 16) {
            bytes.clear();
            chunk.iter().for_each(|t| triangle_bytes(t, &mut bytes));
            self.put(&bytes)?;
        }
        Ok(())
    }

    /// Zeros up to the next [`ALIGN`] boundary after a section of `len` bytes.
    fn pad(&mut self, len: usize) -> io::Result<()> {
        self.put(&[0u8; ALIGN][..padding(len)])
    }

    /// Writes the checksum of everything put.
    pub(crate) fn finish(mut self) -> io::Result<()> {
        if !self.block.is_empty() {
            self.blocks.push(block_hash(&self.block));
        }
        let sum = fold_blocks(&self.blocks, self.len);
        self.w.write_all(&sum.to_le_bytes())
    }
}

/// A BVH file nested in another (a world's geometry) writes through the outer hash.
impl<W: Write + ?Sized> Write for Hashing<'_, W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.put(buf)?;
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        self.w.flush()
    }
}

/// Zero bytes after `len` bytes up to the next [`ALIGN`] boundary.
fn padding(len: usize) -> usize {
    (ALIGN - len % ALIGN) % ALIGN
}

// ---------------------------------------------------------------------------------------
// The header.

/// The layout's tag in the file: its position in [`Layout::ALL`] plus one (0 is no layout).
fn layout_tag(layout: Layout) -> u8 {
    Layout::ALL
        .iter()
        .position(|&l| l == layout)
        .expect("every layout is in ALL") as u8
        + 1
}

/// Bytes of one node of `layout`.
fn node_size(layout: Layout) -> usize {
    match layout {
        Layout::Bvh4Dfs | Layout::Bvh4Subtree => std::mem::size_of::<Bvh4Node>(),
        Layout::Bvh4Quant => std::mem::size_of::<QBvh4Node>(),
        Layout::Bvh8Dfs => std::mem::size_of::<Bvh8Node>(),
        _ => std::mem::size_of::<Bvh2Node>(),
    }
}

/// Element sizes of the sections of a file of `layout`, in [`SECTIONS`] order.
fn element_sizes(layout: Layout) -> [usize; 5] {
    [
        node_size(layout),
        TRIANGLE_BYTES,
        4,
        std::mem::size_of::<Tri4>(),
        4,
    ]
}

/// What the header says.
struct Header {
    layout: Layout,
    frame: Frame,
    inputs: Inputs,
    /// Every primitive's box in the caller's units ([`Bvh::bounds`]).
    bounds: Aabb,
    /// The same in the layout's frame (what a wide layout keeps).
    layout_bounds: Aabb,
    /// Elements in each section, in [`SECTIONS`] order.
    counts: [u64; 5],
}

fn box_bytes(b: &Aabb) -> [u8; 24] {
    let mut out = [0u8; 24];
    let v = [b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z];
    for (o, x) in out.chunks_exact_mut(4).zip(v) {
        o.copy_from_slice(&x.to_le_bytes());
    }
    out
}

impl Header {
    fn bytes(&self) -> [u8; HEADER] {
        let mut h = [0u8; HEADER];
        h[0..8].copy_from_slice(&MAGIC);
        h[8..12].copy_from_slice(&Bvh::FORMAT_VERSION.to_le_bytes());
        // Native order: a reader of the other order sees the bytes reversed.
        h[12..16].copy_from_slice(&ENDIAN.to_ne_bytes());
        h[16] = layout_tag(self.layout);
        h[17] = LEAF_TRIANGLE;
        h[20..24].copy_from_slice(&(node_size(self.layout) as u32).to_le_bytes());
        h[24..28].copy_from_slice(&self.frame.exponent().to_le_bytes());
        h[32..40].copy_from_slice(&(self.inputs.len as u64).to_le_bytes());
        h[40..48].copy_from_slice(&(self.inputs.held as u64).to_le_bytes());
        h[48..72].copy_from_slice(&box_bytes(&self.bounds));
        h[72..96].copy_from_slice(&box_bytes(&self.layout_bounds));
        for (i, c) in self.counts.iter().enumerate() {
            h[96 + 8 * i..104 + 8 * i].copy_from_slice(&c.to_le_bytes());
        }
        h
    }

    /// Reads the header of `h` (the first [`HEADER`] bytes, or fewer: then only as far as
    /// they go, and the error is the first thing they show wrong or [`LoadError::Truncated`]).
    fn parse(h: &[u8]) -> Result<Header, LoadError> {
        let truncated = || LoadError::Truncated {
            section: "header",
            need: HEADER as u64,
            have: h.len() as u64,
        };
        preamble(h, &MAGIC, HEADER as u64, Bvh::FORMAT_VERSION)?;
        if h.len() < HEADER {
            return Err(truncated());
        }
        let u32_at = |at: usize| u32::from_le_bytes(h[at..at + 4].try_into().expect("4"));
        let u64_at = |at: usize| u64::from_le_bytes(h[at..at + 8].try_into().expect("8"));
        let f32_at = |at: usize| f32::from_le_bytes(h[at..at + 4].try_into().expect("4"));
        let bad = |field, value| Err(LoadError::BadHeader { field, value });
        let tag = h[16] as usize;
        let Some(&layout) = tag.checked_sub(1).and_then(|i| Layout::ALL.get(i)) else {
            return bad("layout", tag as u64);
        };
        if h[17] != LEAF_TRIANGLE {
            return bad("leaf format", h[17] as u64);
        }
        if u32_at(20) as usize != node_size(layout) {
            return bad("node size", u32_at(20) as u64);
        }
        let k = i32::from_le_bytes(h[24..28].try_into().expect("4"));
        let Some(frame) = Frame::from_exponent(k) else {
            return bad("frame", k as u32 as u64);
        };
        for (at, field) in [(18, "reserved"), (19, "reserved")] {
            if h[at] != 0 {
                return bad(field, h[at] as u64);
            }
        }
        if u32_at(28) != 0 {
            return bad("reserved", u32_at(28) as u64);
        }
        if let Some(at) = (136..HEADER).find(|&at| h[at] != 0) {
            return bad("reserved", at as u64);
        }
        let (len, held) = (u64_at(32), u64_at(40));
        if held > len || usize::try_from(len).is_err() {
            return bad("held inputs", held);
        }
        let read_box = |at: usize, field| {
            let b = Aabb::new(
                Vec3A::new(f32_at(at), f32_at(at + 4), f32_at(at + 8)),
                Vec3A::new(f32_at(at + 12), f32_at(at + 16), f32_at(at + 20)),
            );
            if box_ok(&b) {
                Ok(b)
            } else {
                Err(LoadError::BadHeader { field, value: 0 })
            }
        };
        let bounds = read_box(48, "bounds")?;
        let layout_bounds = read_box(72, "layout bounds")?;
        let counts = std::array::from_fn(|i| u64_at(96 + 8 * i));
        Ok(Header {
            layout,
            frame,
            inputs: Inputs {
                len: len as usize,
                held: held as usize,
            },
            bounds,
            layout_bounds,
            counts,
        })
    }

    /// Byte ranges of the sections (unpadded) and the file's total length, checked for
    /// overflow.
    fn extents(&self) -> Result<([(usize, usize); 5], u64), LoadError> {
        let sizes = element_sizes(self.layout);
        let mut at = HEADER as u64;
        let mut out = [(0usize, 0usize); 5];
        for (i, (slot, (&count, size))) in out
            .iter_mut()
            .zip(self.counts.iter().zip(sizes))
            .enumerate()
        {
            let bytes = count
                .checked_mul(size as u64)
                .ok_or_else(|| overflow_of(i))?;
            let padded = bytes
                .checked_add(ALIGN as u64 - 1)
                .map(|b| b / ALIGN as u64 * ALIGN as u64)
                .ok_or_else(|| overflow_of(i))?;
            let end = at.checked_add(padded).ok_or_else(|| overflow_of(i))?;
            // The offsets must be addressable on this machine.
            let start = usize::try_from(at).map_err(|_| overflow_of(i))?;
            let len = usize::try_from(bytes).map_err(|_| overflow_of(i))?;
            usize::try_from(end).map_err(|_| overflow_of(i))?;
            *slot = (start, len);
            at = end;
        }
        let total = at.checked_add(8).ok_or(LoadError::LengthOverflow {
            section: "checksum",
        })?;
        Ok((out, total))
    }
}

fn overflow_of(i: usize) -> LoadError {
    LoadError::LengthOverflow {
        section: SECTIONS[i],
    }
}

/// A box a file may hold: finite, or exactly the empty box (an unused slot's, an empty
/// scene's).
fn box_ok(b: &Aabb) -> bool {
    (b.min.is_finite() && b.max.is_finite())
        || (b.min == Vec3A::INFINITY && b.max == Vec3A::NEG_INFINITY)
}

// ---------------------------------------------------------------------------------------
// Saving.

/// A layout's arrays as the file stores them.
struct Parts<'a> {
    layout: Layout,
    nodes: &'a [u8],
    node_count: usize,
    triangles: &'a [Triangle],
    ids: &'a [u32],
    groups: &'a [Tri4],
    far: &'a [u32],
    inputs: Inputs,
    layout_bounds: Aabb,
}

fn parts(layout: &AnyLayout<Triangle>) -> Parts<'_> {
    match layout {
        AnyLayout::Bvh2(b) => Parts {
            layout: match b.mapping {
                Bvh2Mapping::DepthFirst => Layout::Bvh2Dfs,
                Bvh2Mapping::BreadthFirst => Layout::Bvh2Bfs,
                Bvh2Mapping::Shuffled => Layout::Bvh2Shuffled,
                Bvh2Mapping::Subtree => Layout::Bvh2Subtree,
                Bvh2Mapping::SubtreePage => Layout::Bvh2SubtreePage,
                Bvh2Mapping::Compact => Layout::Bvh2Compact,
                Bvh2Mapping::CompactPage => Layout::Bvh2CompactPage,
            },
            nodes: bytemuck::cast_slice(&b.nodes),
            node_count: b.nodes.len(),
            triangles: &b.prims,
            ids: &b.prim_ids,
            groups: &[],
            far: &[],
            inputs: b.inputs,
            layout_bounds: b.nodes.first().map_or(Aabb::EMPTY, Bvh2Node::bounds),
        },
        AnyLayout::Bvh4(b) => Parts {
            layout: match b.mapping {
                Bvh4Mapping::DepthFirst => Layout::Bvh4Dfs,
                Bvh4Mapping::Subtree => Layout::Bvh4Subtree,
            },
            nodes: bytemuck::cast_slice(&b.nodes),
            node_count: b.nodes.len(),
            triangles: &b.prims,
            ids: &b.prim_ids,
            groups: &b.tri4,
            far: b.far.ids(),
            inputs: b.inputs,
            layout_bounds: b.bounds,
        },
        AnyLayout::QBvh4(b) => Parts {
            layout: Layout::Bvh4Quant,
            nodes: bytemuck::cast_slice(&b.nodes),
            node_count: b.nodes.len(),
            triangles: &b.prims,
            ids: &b.prim_ids,
            groups: &b.tri4,
            far: b.far.ids(),
            inputs: b.inputs,
            layout_bounds: b.bounds,
        },
        AnyLayout::Bvh8(b) => Parts {
            layout: Layout::Bvh8Dfs,
            nodes: bytemuck::cast_slice(&b.nodes),
            node_count: b.nodes.len(),
            triangles: &b.prims,
            ids: &b.prim_ids,
            groups: &b.tri4,
            far: b.far.ids(),
            inputs: b.inputs,
            layout_bounds: b.bounds,
        },
    }
}

/// Checks the first 16 bytes every quiver file starts with (a BVH file's or a world's,
/// `magic` says which; `h` may be shorter, or longer): the magic first (a prefix of it is
/// judged as far as it goes), then the format version, then the byte order, since a file of
/// another version may have another header. [`LoadError::Truncated`] (the header being `need`
/// bytes) where `h` ends before them. The version (1 to `newest`, the newest this quiver reads
/// of the file's kind) is the answer.
pub(crate) fn preamble(
    h: &[u8],
    magic: &[u8; 8],
    need: u64,
    newest: u32,
) -> Result<u32, LoadError> {
    if h[..h.len().min(8)] != magic[..h.len().min(8)] {
        return Err(LoadError::BadMagic);
    }
    if h.len() < 16 {
        return Err(LoadError::Truncated {
            section: "header",
            need,
            have: h.len() as u64,
        });
    }
    let version = u32::from_le_bytes(h[8..12].try_into().expect("4"));
    if version == 0 || version > newest {
        return Err(LoadError::UnsupportedVersion {
            found: version,
            supported: newest,
        });
    }
    let marker = u32::from_ne_bytes(h[12..16].try_into().expect("4"));
    if marker == ENDIAN.swap_bytes() {
        return Err(LoadError::WrongEndianness);
    }
    if marker != ENDIAN {
        return Err(LoadError::BadHeader {
            field: "endianness",
            value: marker as u64,
        });
    }
    Ok(version)
}

/// Appends a triangle's nine coordinates, little-endian.
pub(crate) fn triangle_bytes(t: &Triangle, out: &mut Vec<u8>) {
    for v in &t.v {
        for x in [v.x, v.y, v.z] {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
}

impl Bvh<Triangle> {
    /// The format version this quiver writes, and the newest it reads (world files,
    /// [`World::save`](crate::World::save)'s, carry the same).
    ///
    /// Compatibility rule: a reader of version `N` reads every version from 1 to `N` (a new
    /// version may add layouts, sections or header fields, never change what an older
    /// version's bytes mean) and refuses a newer one with [`LoadError::UnsupportedVersion`];
    /// within one version the layout of the bytes is frozen.
    ///
    /// ```
    /// assert_eq!(quiver_rt::Bvh::FORMAT_VERSION, 1);
    /// ```
    pub const FORMAT_VERSION: u32 = 1;

    /// Writes the BVH to `w` in quiver's file format (`docs/file-format.md`): the node and
    /// leaf arrays as they are in memory, with a header and a checksum. [`Bvh::load`] reads
    /// it back, on this machine or another of the same byte order, whatever its instruction
    /// set. `w` gets the bytes in a few large writes; wrap a file in a
    /// [`std::io::BufWriter`] only if it is unbuffered and the BVH tiny.
    ///
    /// ```
    /// use quiver_rt::{BuildOptions, Bvh, Layout, Ray, RayQuery, Triangle};
    /// use quiver_rt::glam::Vec3A;
    /// let tris: Vec<Triangle> = (0..100)
    ///     .map(|i| Triangle::new(Vec3A::new(i as f32, 0.0, 0.0), Vec3A::new(i as f32 + 1.0, 0.0, 0.0), Vec3A::new(i as f32, 1.0, 0.0)))
    ///     .collect();
    /// let bvh = Bvh::build(&tris, &BuildOptions::default().layout(Layout::Bvh4Quant))?;
    /// let mut file = Vec::new();
    /// bvh.save(&mut file)?;
    /// let loaded = Bvh::load(&mut &file[..])?;
    /// let ray = Ray::new(Vec3A::new(41.2, 0.3, 1.0), -Vec3A::Z);
    /// assert_eq!(loaded.closest_hit(&ray), bvh.closest_hit(&ray));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// What `w` returns.
    pub fn save<W: Write + ?Sized>(&self, w: &mut W) -> io::Result<()> {
        let p = parts(&self.layout);
        let header = Header {
            layout: p.layout,
            frame: self.frame,
            inputs: p.inputs,
            bounds: self.bounds,
            layout_bounds: p.layout_bounds,
            counts: [
                p.node_count as u64,
                p.triangles.len() as u64,
                p.ids.len() as u64,
                p.groups.len() as u64,
                p.far.len() as u64,
            ],
        };
        let mut out = Hashing::new(w);
        out.put(&header.bytes())?;
        // The Pod arrays are written as they are in memory: little-endian on every machine
        // quiver loads on (the header's marker refuses the others).
        out.put(p.nodes)?;
        out.pad(p.nodes.len())?;
        out.put_triangles(p.triangles)?;
        out.pad(p.triangles.len() * TRIANGLE_BYTES)?;
        for bytes in [
            bytemuck::cast_slice::<u32, u8>(p.ids),
            bytemuck::cast_slice(p.groups),
            bytemuck::cast_slice(p.far),
        ] {
            out.put(bytes)?;
            out.pad(bytes.len())?;
        }
        out.finish()
    }

    /// The BVH as the bytes [`Bvh::save`] writes.
    ///
    /// ```
    /// use quiver_rt::{Bvh, Triangle};
    /// use quiver_rt::glam::Vec3A;
    /// let bvh = Bvh::new(&[Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)]);
    /// let bytes = bvh.to_bytes();
    /// assert_eq!(&bytes[..7], b"QUIVBVH");
    /// assert_eq!(Bvh::from_bytes(&bytes)?.to_bytes(), bytes);
    /// # Ok::<(), quiver_rt::LoadError>(())
    /// ```
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(HEADER + self.footprint().kept + 8 * ALIGN);
        self.save(&mut out).expect("writing to a Vec does not fail");
        out
    }

    /// Reads one BVH that [`Bvh::save`] wrote from `r`, checked completely before it is
    /// returned (see [`Bvh::from_bytes`]). Reads exactly the file's bytes, so files can
    /// follow one another in a stream; memory grows with the bytes actually read, never
    /// with lengths the header only claims.
    ///
    /// ```
    /// use quiver_rt::{Bvh, LoadError, Triangle};
    /// use quiver_rt::glam::Vec3A;
    /// let a = Bvh::new(&[Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)]);
    /// let b = Bvh::new(&[Triangle::new(Vec3A::ZERO, Vec3A::Y, Vec3A::Z)]);
    /// let mut stream = a.to_bytes();
    /// b.save(&mut stream)?;
    /// let mut r = &stream[..];
    /// assert_eq!(Bvh::load(&mut r)?.bounds(), a.bounds());
    /// assert_eq!(Bvh::load(&mut r)?.bounds(), b.bounds());
    /// assert!(matches!(Bvh::load(&mut r), Err(LoadError::Truncated { have: 0, .. })));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`LoadError`]: the reader's error, or what is wrong with the bytes.
    pub fn load<R: Read + ?Sized>(r: &mut R) -> Result<Self, LoadError> {
        let mut head = [0u8; HEADER];
        let mut got = 0;
        while got < HEADER {
            match r.read(&mut head[got..]) {
                Ok(0) => break,
                Ok(n) => got += n.min(HEADER - got),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e.into()),
            }
        }
        let header = Header::parse(&head[..got])?;
        read_bvh(&header, Source::new(r, &header, Some(&head))?)
    }

    /// The BVH in `bytes`, which hold exactly one file [`Bvh::save`] wrote. Nothing is
    /// trusted: the header, every length against the bytes present (before anything is
    /// allocated), the checksum, then the whole structure in one linear pass — every child
    /// link in range, every node reached exactly once from the root, no node deeper than the
    /// kernels' stacks, every box finite (or empty), every leaf the next range of its array,
    /// every SIMD lane the input index leaf order gives it — before the first query. The
    /// arrays are copied out of `bytes` (which need no alignment); the kernels are the best
    /// this CPU runs ([`Isa::detect`]).
    ///
    /// ```
    /// use quiver_rt::{Bvh, LoadError, Triangle};
    /// use quiver_rt::glam::Vec3A;
    /// let bvh = Bvh::new(&[Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)]);
    /// let bytes = bvh.to_bytes();
    /// assert_eq!(Bvh::from_bytes(&bytes)?.footprint(), bvh.footprint());
    /// let mut newer = bytes.clone();
    /// newer[8] = 2; // the format version
    /// assert!(matches!(
    ///     Bvh::from_bytes(&newer),
    ///     Err(LoadError::UnsupportedVersion { found: 2, supported: 1 })
    /// ));
    /// # Ok::<(), LoadError>(())
    /// ```
    ///
    /// # Errors
    /// [`LoadError`], naming what is wrong and where.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, LoadError> {
        let header = Header::parse(&bytes[..bytes.len().min(HEADER)])?;
        let (extents, total) = header.extents()?;
        let have = bytes.len() as u64;
        for (i, &(start, len)) in extents.iter().enumerate() {
            let end = (start + len + padding(len)) as u64;
            if end > have {
                return Err(LoadError::Truncated {
                    section: SECTIONS[i],
                    need: end,
                    have,
                });
            }
        }
        if total > have {
            return Err(LoadError::Truncated {
                section: "checksum",
                need: total,
                have,
            });
        }
        if total < have {
            return Err(LoadError::TrailingBytes {
                extra: have - total,
            });
        }
        // All the bytes are here: hashed first, in parallel, then copied unhashed.
        let end = total as usize - 8;
        let stored = u64::from_le_bytes(bytes[end..].try_into().expect("8 bytes"));
        let computed = checksum(&bytes[..end]);
        if stored != computed {
            return Err(LoadError::Checksum { stored, computed });
        }
        let mut rest = &bytes[HEADER..];
        read_bvh(&header, Source::new(&mut rest, &header, None)?)
    }
}

// ---------------------------------------------------------------------------------------
// Loading and checking.

/// The length of the BVH file `bytes` begin with, as its header gives it (checked for
/// overflow, not against the bytes present).
pub(crate) fn saved_len(bytes: &[u8]) -> Result<u64, LoadError> {
    let header = Header::parse(&bytes[..bytes.len().min(HEADER)])?;
    Ok(header.extents()?.1)
}

/// How many input triangles `bvh` was built over (its input indices run below this).
pub(crate) fn input_count(bvh: &Bvh<Triangle>) -> usize {
    parts(&bvh.layout).inputs.len
}

/// The triangles of a section (nine little-endian f32 each).
pub(crate) fn read_triangles(bytes: &[u8]) -> Vec<Triangle> {
    bytes
        .chunks_exact(TRIANGLE_BYTES)
        .map(triangle_from_bytes)
        .collect()
}

/// Bytes read, zeroed, hashed and checked at a time: small enough to stay in cache from
/// the read to the hash, large enough that a file costs few reads.
const PIECE: usize = 1 << 18;

/// The most a section reserves before its bytes arrive (beyond it, its array grows as they
/// do): a header's claimed lengths cost no more than this.
const RESERVE: usize = 1 << 26;

/// A file's sections as the loader takes them from a reader: each read in pieces straight
/// into the array it fills (no whole-file buffer, no second copy), hashed while the piece is
/// still in cache, then the checksum compared.
struct Source<'r, R: ?Sized> {
    r: &'r mut R,
    /// The checksum so far; `None` where the caller compared it before.
    sum: Option<StreamSum>,
    /// The most elements an array is given before its bytes arrive.
    reserve: usize,
    /// Where each section's padding ends, then where the checksum ends.
    ends: [u64; 6],
    counts: [usize; 5],
    /// Bytes taken from the file so far (the header's included).
    at: u64,
    /// The first section whose padding is not zero, reported once the checksum matches.
    bad_padding: Option<usize>,
}

impl<'r, R: Read + ?Sized> Source<'r, R> {
    /// The sections of the file whose parsed header is `header`, from `r`, which holds the
    /// bytes after the header; `head`, the header's bytes, to start the checksum with, or
    /// `None` where every byte is in memory, its lengths and checksum compared already (then
    /// each array is allocated whole at once).
    fn new(r: &'r mut R, header: &Header, head: Option<&[u8]>) -> Result<Self, LoadError> {
        let (extents, total) = header.extents()?;
        let mut ends = [total; 6];
        for (end, &(start, len)) in ends.iter_mut().zip(&extents) {
            *end = (start + len + padding(len)) as u64;
        }
        let reserve = if head.is_some() { RESERVE } else { usize::MAX };
        let sum = head.map(|head| {
            let mut sum = StreamSum::new();
            sum.put(head);
            sum
        });
        Ok(Source {
            r,
            sum,
            reserve,
            ends,
            // Each fits: `extents` checked its bytes against the address space.
            counts: header.counts.map(|c| c as usize),
            at: HEADER as u64,
            bad_padding: None,
        })
    }

    /// Fills `buf` with the next bytes of part `part` (a section, or 5: the checksum), which
    /// the reader must hold: [`LoadError::Truncated`] where it ends first.
    fn fill(&mut self, buf: &mut [u8], part: usize) -> Result<(), LoadError> {
        let mut got = 0;
        while got < buf.len() {
            match self.r.read(&mut buf[got..]) {
                Ok(0) => {
                    return Err(LoadError::Truncated {
                        section: SECTIONS.get(part).copied().unwrap_or("checksum"),
                        need: self.ends[part],
                        have: self.at + got as u64,
                    })
                }
                // `min`: a reader claiming more than it was given gets no index past `buf`.
                Ok(n) => got += n.min(buf.len() - got),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e.into()),
            }
        }
        self.at += got as u64;
        Ok(())
    }

    /// Section `i` as an array of `T`, read into the array itself a piece at a time.
    fn pod<T: Pod>(&mut self, i: usize) -> Result<Vec<T>, LoadError> {
        let (count, size) = (self.counts[i], std::mem::size_of::<T>());
        let step = (PIECE / size).max(1);
        // The read needs initialized bytes: zeroed pages fresh from the system (no work
        // until touched), as far as a header may reserve ahead of its bytes; past that the
        // array grows, zeroed in pieces, only as bytes arrive.
        let mut v: Vec<T> = crate::mem::zeroed_vec(count.min(self.reserve / size));
        let mut filled = 0;
        while filled < count {
            if v.len() == filled {
                v.resize(filled + step.min(count - filled), T::zeroed());
            }
            let end = v.len().min(filled + step);
            let piece: &mut [u8] = bytemuck::cast_slice_mut(&mut v[filled..end]);
            self.fill(piece, i)?;
            self.hash(piece);
            filled = end;
        }
        self.pad(i, count * size)?;
        Ok(v)
    }

    /// The triangles section (nine little-endian f32 each) as triangles.
    fn triangles(&mut self) -> Result<Vec<Triangle>, LoadError> {
        let count = self.counts[1];
        let step = PIECE / TRIANGLE_BYTES;
        let mut out = crate::mem::with_capacity(count.min(self.reserve / size_of::<Triangle>()));
        let mut buf = vec![0u8; count.min(step) * TRIANGLE_BYTES];
        while out.len() < count {
            let piece = &mut buf[..step.min(count - out.len()) * TRIANGLE_BYTES];
            self.fill(piece, 1)?;
            self.hash(piece);
            out.extend(piece.chunks_exact(TRIANGLE_BYTES).map(triangle_from_bytes));
        }
        self.pad(1, count * TRIANGLE_BYTES)?;
        Ok(out)
    }

    fn hash(&mut self, bytes: &[u8]) {
        if let Some(sum) = &mut self.sum {
            sum.put(bytes);
        }
    }

    /// The zeros after section `i`'s `len` bytes.
    fn pad(&mut self, i: usize, len: usize) -> Result<(), LoadError> {
        let mut zeros = [0u8; ALIGN];
        let zeros = &mut zeros[..padding(len)];
        self.fill(zeros, i)?;
        self.hash(zeros);
        if self.bad_padding.is_none() && zeros.iter().any(|&b| b != 0) {
            self.bad_padding = Some(i);
        }
        Ok(())
    }

    /// Reads the stored checksum and compares it with the bytes', then the padding.
    fn finish(mut self) -> Result<(), LoadError> {
        let mut stored = [0u8; 8];
        self.fill(&mut stored, 5)?;
        if let Some(sum) = self.sum {
            let (stored, computed) = (u64::from_le_bytes(stored), sum.finish());
            if stored != computed {
                return Err(LoadError::Checksum { stored, computed });
            }
        }
        match self.bad_padding {
            Some(i) => Err(LoadError::Padding {
                section: SECTIONS[i],
            }),
            None => Ok(()),
        }
    }
}

/// A triangle from its nine little-endian f32.
fn triangle_from_bytes(b: &[u8]) -> Triangle {
    let f = |i: usize| f32::from_le_bytes(b[4 * i..4 * i + 4].try_into().expect("4 bytes"));
    Triangle::new(
        Vec3A::new(f(0), f(1), f(2)),
        Vec3A::new(f(3), f(4), f(5)),
        Vec3A::new(f(6), f(7), f(8)),
    )
}

/// The five sections of a file whose nodes are `N`, read and checksummed, the input indices
/// checked against the number of inputs.
struct Sections<N> {
    nodes: Vec<N>,
    prims: Vec<Triangle>,
    ids: Vec<u32>,
    groups: Vec<Tri4>,
    far: Vec<u32>,
}

fn read_sections<N: Pod, R: Read + ?Sized>(
    h: &Header,
    mut src: Source<'_, R>,
) -> Result<Sections<N>, LoadError> {
    let s = Sections {
        nodes: src.pod(0)?,
        prims: src.triangles()?,
        ids: src.pod(2)?,
        groups: src.pod(3)?,
        far: src.pod(4)?,
    };
    src.finish()?;
    let n_inputs = h.inputs.len as u64;
    if let Some((at, &id)) = s
        .ids
        .iter()
        .enumerate()
        .find(|(_, &i)| i as u64 >= n_inputs)
    {
        return Err(LoadError::IdOutOfRange {
            at,
            id,
            len: n_inputs,
        });
    }
    Ok(s)
}

fn len_err(section: &'static str, len: usize, why: &'static str) -> LoadError {
    LoadError::SectionLength {
        section,
        len: len as u64,
        why,
    }
}

/// The BVH of a file whose header is `h`, its sections from `src`.
fn read_bvh<R: Read + ?Sized>(h: &Header, src: Source<'_, R>) -> Result<Bvh, LoadError> {
    Ok(Bvh {
        layout: read_layout(h, src)?,
        frame: h.frame,
        bounds: h.bounds,
    })
}

/// A binary layout's sections, checked.
fn bvh2(
    h: &Header,
    mapping: Bvh2Mapping,
    s: Sections<Bvh2Node>,
) -> Result<AnyLayout<Triangle>, LoadError> {
    if !s.groups.is_empty() {
        return Err(len_err(
            "groups",
            s.groups.len(),
            "binary layouts have none",
        ));
    }
    if !s.far.is_empty() {
        return Err(len_err("far", s.far.len(), "binary layouts have none"));
    }
    if s.prims.len() != s.ids.len() {
        return Err(len_err("ids", s.ids.len(), "one per leaf-order triangle"));
    }
    check_bvh2(&s.nodes, mapping, s.prims.len())?;
    Ok(AnyLayout::Bvh2(Bvh2 {
        nodes: s.nodes,
        prims: s.prims,
        prim_ids: s.ids,
        mapping,
        inputs: h.inputs,
    }))
}

/// A wide layout's leaf sections, checked (the nodes are checked against them after).
fn wide_parts<N>(s: &mut Sections<N>) -> Result<(Vec<Tri4>, FarGroups), LoadError> {
    if !s.prims.is_empty() {
        return Err(len_err(
            "triangles",
            s.prims.len(),
            "wide layouts keep their triangles in groups",
        ));
    }
    let (groups, far) = (std::mem::take(&mut s.groups), std::mem::take(&mut s.far));
    for (at, w) in far.windows(2).enumerate() {
        if w[0] >= w[1] {
            return Err(LoadError::FarGroup { at: at + 1 });
        }
    }
    if let Some(&last) = far.last() {
        if last as usize >= groups.len() {
            return Err(LoadError::FarGroup { at: far.len() - 1 });
        }
    }
    Ok((groups, FarGroups::from_checked(far)))
}

/// Reads the sections for the header's layout, checks them against it and each other, and
/// builds the layout.
fn read_layout<R: Read + ?Sized>(
    h: &Header,
    src: Source<'_, R>,
) -> Result<AnyLayout<Triangle>, LoadError> {
    let isa = Isa::detect();
    Ok(match h.layout {
        Layout::Bvh2Dfs => bvh2(h, Bvh2Mapping::DepthFirst, read_sections(h, src)?)?,
        Layout::Bvh2Bfs => bvh2(h, Bvh2Mapping::BreadthFirst, read_sections(h, src)?)?,
        Layout::Bvh2Shuffled => bvh2(h, Bvh2Mapping::Shuffled, read_sections(h, src)?)?,
        Layout::Bvh2Subtree => bvh2(h, Bvh2Mapping::Subtree, read_sections(h, src)?)?,
        Layout::Bvh2SubtreePage => bvh2(h, Bvh2Mapping::SubtreePage, read_sections(h, src)?)?,
        Layout::Bvh2Compact => bvh2(h, Bvh2Mapping::Compact, read_sections(h, src)?)?,
        Layout::Bvh2CompactPage => bvh2(h, Bvh2Mapping::CompactPage, read_sections(h, src)?)?,
        Layout::Bvh4Dfs | Layout::Bvh4Subtree => {
            let mapping = if h.layout == Layout::Bvh4Dfs {
                Bvh4Mapping::DepthFirst
            } else {
                Bvh4Mapping::Subtree
            };
            let mut s = read_sections::<Bvh4Node, R>(h, src)?;
            let (tri4, far) = wide_parts(&mut s)?;
            check_wide::<4, _>(&s.nodes, mapping == Bvh4Mapping::DepthFirst, &s.ids, &tri4)?;
            AnyLayout::Bvh4(Bvh4 {
                nodes: s.nodes,
                prims: Vec::new(),
                prim_ids: s.ids,
                tri4,
                far,
                mapping,
                kernels: Kernels::new(isa),
                bounds: h.layout_bounds,
                inputs: h.inputs,
            })
        }
        Layout::Bvh4Quant => {
            let mut s = read_sections::<QBvh4Node, R>(h, src)?;
            let (tri4, far) = wide_parts(&mut s)?;
            check_wide::<4, _>(&s.nodes, true, &s.ids, &tri4)?;
            AnyLayout::QBvh4(Bvh4 {
                nodes: s.nodes,
                prims: Vec::new(),
                prim_ids: s.ids,
                tri4,
                far,
                mapping: Bvh4Mapping::DepthFirst,
                kernels: Kernels::new(isa),
                bounds: h.layout_bounds,
                inputs: h.inputs,
            })
        }
        Layout::Bvh8Dfs => {
            let mut s = read_sections::<Bvh8Node, R>(h, src)?;
            let (tri4, far) = wide_parts(&mut s)?;
            check_wide::<8, _>(&s.nodes, true, &s.ids, &tri4)?;
            AnyLayout::Bvh8(Bvh8 {
                nodes: s.nodes,
                prims: Vec::new(),
                prim_ids: s.ids,
                tri4,
                far,
                kernels: Kernels::new(isa),
                bounds: h.layout_bounds,
                inputs: h.inputs,
            })
        }
    })
}

/// The padding slot of a binary layout (an empty leaf no link reaches).
fn bvh2_padding() -> Bvh2Node {
    Bvh2Node {
        min: [f32::INFINITY; 3],
        link: 0,
        max: [f32::NEG_INFINITY; 3],
        count: Bvh2Node::LEAF,
    }
}

/// Checks a binary layout's nodes over `n_prims` leaf-order triangles, reading every link
/// as the traversal of `mapping` reads it (`traverse/bvh2.rs`).
fn check_bvh2(nodes: &[Bvh2Node], mapping: Bvh2Mapping, n_prims: usize) -> Result<(), LoadError> {
    let n = nodes.len();
    if n == 0 {
        return Err(LoadError::SectionLength {
            section: "nodes",
            len: 0,
            why: "the root is node 0",
        });
    }
    let dfs = mapping == Bvh2Mapping::DepthFirst;
    let addressing = mapping.addressing();
    let mut seen = vec![false; n];
    // (node, depth); the right child is pushed first, so nodes come off in preorder and
    // leaves in leaf order.
    let mut stack = vec![(0usize, 0usize)];
    let (mut visits, mut next_prim) = (0usize, 0u64);
    while let Some((i, depth)) = stack.pop() {
        if std::mem::replace(&mut seen[i], true) {
            return Err(LoadError::NotATree { node: i });
        }
        if dfs && i != visits {
            return Err(LoadError::NotPreorder {
                node: i,
                expected: visits,
            });
        }
        visits += 1;
        if depth > MAX_DEPTH {
            return Err(LoadError::TooDeep {
                depth,
                max: MAX_DEPTH,
            });
        }
        let node = &nodes[i];
        if !box_ok(&node.bounds()) {
            return Err(LoadError::NonFiniteBox { node: i });
        }
        if node.is_leaf() {
            let (first, count) = (node.link as u64, node.prim_count() as u64);
            let expected = if count == 0 { first } else { next_prim };
            if first != expected || first + count > n_prims as u64 {
                return Err(LoadError::PrimitiveOutOfRange {
                    node: i,
                    first,
                    count,
                    expected,
                    len: n_prims as u64,
                });
            }
            next_prim += count;
            continue;
        }
        let (l, r) = match addressing {
            Addressing::DepthFirst => (i as u64 + 1, node.link as u64),
            Addressing::Explicit => (node.link as u64, node.count as u64),
            Addressing::Compact if node.count == 0 => {
                // A block node's children are found by position in a block of height
                // `link` (`compact_children`); a height past 16 is no block quiver makes
                // and would overflow the traversal's shift.
                let h = node.link;
                if !(1..=16).contains(&h) {
                    return Err(LoadError::ChildOutOfRange {
                        node: i,
                        child: h as u64,
                    });
                }
                let p = i as u64 & ((1u64 << h) - 1);
                (i as u64 + p, i as u64 + p + 1)
            }
            Addressing::Compact => (node.link as u64, node.count as u64),
        };
        for c in [l, r] {
            if c >= n as u64 {
                return Err(LoadError::ChildOutOfRange { node: i, child: c });
            }
        }
        stack.push((r as usize, depth + 1));
        stack.push((l as usize, depth + 1));
    }
    if next_prim != n_prims as u64 {
        return Err(LoadError::Coverage {
            section: "triangles",
            covered: next_prim,
            len: n_prims as u64,
        });
    }
    // A depth-first layout leaves no padding; the block orders leave empty leaves.
    let pad = bvh2_padding();
    let unused = |i: usize| !dfs && bytemuck::bytes_of(&nodes[i]) == bytemuck::bytes_of(&pad);
    match (0..n).find(|&i| !seen[i] && !unused(i)) {
        Some(node) => Err(LoadError::Unreached { node }),
        None => Ok(()),
    }
}

/// A wide node format as the loader reads it: its slots as the kernels read them, whether
/// its boxes may be trusted, and the padding slot of a layout that leaves some.
trait WideSaved<const W: usize>: Pod {
    /// Slot `i` as (node index or first group, `LEAF | count` for a leaf, 0 for inner).
    fn slot(&self, i: usize) -> (u32, u32);
    /// Every box finite (or empty), or the quantization frame finite and in range.
    fn boxes_ok(&self) -> bool;
    /// The node a layout places in a slot no link reaches.
    fn padding() -> Self;
}

/// Whether slot `i` of `W` lanes of six plane rows is a finite box or the empty box.
fn lane_box_ok<const W: usize>(planes: &[[f32; W]; 6], i: usize) -> bool {
    let b = Aabb::new(
        Vec3A::new(planes[0][i], planes[1][i], planes[2][i]),
        Vec3A::new(planes[3][i], planes[4][i], planes[5][i]),
    );
    box_ok(&b)
}

impl WideSaved<8> for Bvh8Node {
    fn slot(&self, i: usize) -> (u32, u32) {
        (self.child[i], self.count[i])
    }
    fn boxes_ok(&self) -> bool {
        (0..8).all(|i| lane_box_ok(&self.planes, i))
    }
    fn padding() -> Self {
        // Never used: the 8-wide layout is depth-first, every node reached.
        Bvh8Node::encode(&Wide::EMPTY)
    }
}

impl WideSaved<4> for Bvh4Node {
    fn slot(&self, i: usize) -> (u32, u32) {
        self.child(i)
    }
    fn boxes_ok(&self) -> bool {
        (0..4).all(|i| lane_box_ok(&self.planes, i))
    }
    fn padding() -> Self {
        Bvh4Node::encode(&Wide::EMPTY, &[])
    }
}

impl WideSaved<4> for QBvh4Node {
    fn slot(&self, i: usize) -> (u32, u32) {
        self.child(i)
    }
    fn boxes_ok(&self) -> bool {
        // Decoded boxes are `origin + q * 2^exp`: finite origins and normal steps (the
        // range the encoder writes) make every decoded plane a number.
        self.origin.iter().all(|o| o.is_finite()) && self.exp.iter().all(|&e| e >= -126)
    }
    fn padding() -> Self {
        QBvh4Node::encode(&Wide::EMPTY, &[])
    }
}

/// One item of the wide walk: a node to enter, or a leaf slot of one to take its ids.
enum Item {
    Node { at: usize, depth: usize },
    Leaf { first: u32, count: u32 },
}

/// Checks a wide layout: the tree as the kernels read it (slots through the format's own
/// decoding), preorder node positions where `dfs`, SIMD groups numbered node by node in
/// preorder, the leaf-order input indices `ids` taken by the leaves in slot order (inner
/// slots' subtrees between), each group's lanes naming them.
fn check_wide<const W: usize, N: WideSaved<W>>(
    nodes: &[N],
    dfs: bool,
    ids: &[u32],
    groups: &[Tri4],
) -> Result<(), LoadError> {
    let n = nodes.len();
    if n == 0 {
        return Err(LoadError::SectionLength {
            section: "nodes",
            len: 0,
            why: "the root is node 0",
        });
    }
    let leaf_flag = Bvh8Node::LEAF; // the same bit in every wide format's decoded slots
    let mut seen = vec![false; n];
    let mut stack = vec![Item::Node { at: 0, depth: 0 }];
    let (mut visits, mut next_group, mut next_id) = (0usize, 0u64, 0usize);
    while let Some(item) = stack.pop() {
        match item {
            Item::Node { at, depth } => {
                if std::mem::replace(&mut seen[at], true) {
                    return Err(LoadError::NotATree { node: at });
                }
                if dfs && at != visits {
                    return Err(LoadError::NotPreorder {
                        node: at,
                        expected: visits,
                    });
                }
                visits += 1;
                if depth > MAX_DEPTH {
                    return Err(LoadError::TooDeep {
                        depth,
                        max: MAX_DEPTH,
                    });
                }
                let node = &nodes[at];
                if !node.boxes_ok() {
                    return Err(LoadError::NonFiniteBox { node: at });
                }
                // The node's leaves own the next groups, in slot order (how the layout
                // packs them: node by node, in preorder).
                for i in 0..W {
                    let (c, count) = node.slot(i);
                    if count & leaf_flag == 0 {
                        if count != 0 {
                            return Err(LoadError::SlotKind {
                                node: at,
                                slot: i,
                                count,
                            });
                        }
                        if c as usize >= n {
                            return Err(LoadError::ChildOutOfRange {
                                node: at,
                                child: c as u64,
                            });
                        }
                        continue;
                    }
                    let count = count & !leaf_flag;
                    let (first, g) = (c as u64, group_count(count) as u64);
                    let expected = if count == 0 { first } else { next_group };
                    if first != expected || first + g > groups.len() as u64 {
                        return Err(LoadError::PrimitiveOutOfRange {
                            node: at,
                            first,
                            count: count as u64,
                            expected,
                            len: groups.len() as u64,
                        });
                    }
                    next_group += g;
                }
                for i in (0..W).rev() {
                    let (c, count) = node.slot(i);
                    if count & leaf_flag == 0 {
                        stack.push(Item::Node {
                            at: c as usize,
                            depth: depth + 1,
                        });
                    } else if count != leaf_flag {
                        stack.push(Item::Leaf {
                            first: c,
                            count: count & !leaf_flag,
                        });
                    }
                }
            }
            Item::Leaf { first, count } => {
                let count = count as usize;
                if next_id + count > ids.len() {
                    return Err(LoadError::Coverage {
                        section: "ids",
                        covered: (next_id + count) as u64,
                        len: ids.len() as u64,
                    });
                }
                let mine = &ids[next_id..next_id + count];
                let first = first as usize;
                for (k, g) in groups[first..first + group_count(count as u32) as usize]
                    .iter()
                    .enumerate()
                {
                    for lane in 0..4 {
                        let want = mine.get(4 * k + lane).copied().unwrap_or(u32::MAX);
                        let unused_ok = want != u32::MAX
                            || g.rows.iter().flatten().all(|row| row[lane].is_nan());
                        if g.id[lane] != want || !unused_ok {
                            return Err(LoadError::GroupLane {
                                group: first + k,
                                lane,
                            });
                        }
                    }
                }
                next_id += count;
            }
        }
    }
    if next_id != ids.len() {
        return Err(LoadError::Coverage {
            section: "ids",
            covered: next_id as u64,
            len: ids.len() as u64,
        });
    }
    if next_group != groups.len() as u64 {
        return Err(LoadError::Coverage {
            section: "groups",
            covered: next_group,
            len: groups.len() as u64,
        });
    }
    // A depth-first layout leaves no padding; the page-subtree order leaves padding nodes.
    let pad = N::padding();
    let unused = |i: usize| !dfs && bytemuck::bytes_of(&nodes[i]) == bytemuck::bytes_of(&pad);
    match (0..n).find(|&i| !seen[i] && !unused(i)) {
        Some(node) => Err(LoadError::Unreached { node }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::soup;
    use crate::{BuildOptions, Hit, Ray, RayQuery};

    /// Rays through the unit cube, half aimed at a triangle (so most hit), half anywhere.
    fn rays(tris: &[Triangle], n: usize, scale: f32) -> Vec<Ray> {
        let mut rng = crate::rng::Rng::new(11);
        (0..n)
            .map(|i| {
                let o = rng.in_box(Vec3A::splat(-0.5), Vec3A::splat(1.5)) * scale;
                let dir = if i % 2 == 0 && !tris.is_empty() {
                    let t = &tris[i % tris.len()];
                    (t.v[0] + t.v[1] + t.v[2]) / 3.0 - o
                } else {
                    rng.in_box(Vec3A::splat(-1.0), Vec3A::ONE)
                };
                Ray::new(o, dir)
            })
            .collect()
    }

    /// Both BVHs answer every ray's closest and any hit the same, single rays and packets.
    fn same_answers(a: &Bvh, b: &Bvh, rays: &[Ray], what: &str) {
        let mut hits = 0;
        for (i, r) in rays.iter().enumerate() {
            let h = a.closest_hit(r);
            hits += h.is_some() as usize;
            assert_eq!(h, b.closest_hit(r), "{what}: ray {i}");
            assert_eq!(a.any_hit(r), b.any_hit(r), "{what}: ray {i}");
        }
        assert!(hits > rays.len() / 4, "{what}: the rays hit ({hits})");
        let (mut ha, mut hb) = (vec![None::<Hit>; rays.len()], vec![None; rays.len()]);
        a.closest_hit_packet(rays, &mut ha);
        b.closest_hit_packet(rays, &mut hb);
        assert_eq!(ha, hb, "{what}: packets");
        let (mut oa, mut ob) = (vec![false; rays.len()], vec![false; rays.len()]);
        a.any_hit_packet(rays, &mut oa);
        b.any_hit_packet(rays, &mut ob);
        assert_eq!(oa, ob, "{what}: occlusion packets");
    }

    #[test]
    fn every_layout_round_trips_bit_identically() {
        let tris = soup(3000, 5);
        let rays = rays(&tris, 1500, 1.0);
        for layout in Layout::ALL {
            let bvh = Bvh::build(&tris, &BuildOptions::default().layout(layout)).unwrap();
            let bytes = bvh.to_bytes();
            let loaded = Bvh::from_bytes(&bytes).unwrap_or_else(|e| panic!("{layout}: {e}"));
            assert_eq!(
                loaded.to_bytes(),
                bytes,
                "{layout}: saved again, the same bytes"
            );
            assert_eq!(loaded.footprint(), bvh.footprint(), "{layout}");
            assert_eq!(loaded.bounds(), bvh.bounds(), "{layout}");
            same_answers(&bvh, &loaded, &rays, layout.name());
            // Through a reader too, and on the portable kernels (as a machine without AVX
            // would load it).
            let read = Bvh::load(&mut &bytes[..]).unwrap();
            same_answers(&bvh, &read.with_isa(Isa::Portable), &rays, layout.name());
        }
    }

    #[test]
    fn a_scaled_frame_and_an_empty_scene_round_trip() {
        let s = 2f32.powi(70);
        let tris: Vec<Triangle> = soup(500, 3)
            .iter()
            .map(|t| Triangle::new(t.v[0] * s, t.v[1] * s, t.v[2] * s))
            .collect();
        for layout in [Layout::Bvh8Dfs, Layout::Bvh2Compact, Layout::Bvh4Quant] {
            let bvh = Bvh::build(&tris, &BuildOptions::default().layout(layout)).unwrap();
            assert!(!bvh.frame.is_identity());
            let loaded = Bvh::from_bytes(&bvh.to_bytes()).unwrap();
            assert_eq!(loaded.frame, bvh.frame);
            same_answers(&bvh, &loaded, &rays(&tris, 300, s), layout.name());
            let empty = Bvh::build(&[], &BuildOptions::default().layout(layout)).unwrap();
            let loaded = Bvh::from_bytes(&empty.to_bytes()).unwrap();
            assert!(loaded.bounds().is_empty());
            assert_eq!(loaded.closest_hit(&Ray::new(Vec3A::ZERO, Vec3A::X)), None);
        }
    }

    #[test]
    fn a_refit_of_a_loaded_bvh_is_the_refit_of_the_saved_one() {
        let tris = soup(2000, 8);
        let moved: Vec<Triangle> = tris
            .iter()
            .map(|t| Triangle::new(t.v[0] * 1.5, t.v[1], t.v[2] + Vec3A::X * 0.01))
            .collect();
        for layout in Layout::ALL {
            let mut bvh = Bvh::build(&tris, &BuildOptions::default().layout(layout)).unwrap();
            let mut loaded = Bvh::from_bytes(&bvh.to_bytes()).unwrap();
            bvh.refit(&moved).unwrap();
            loaded.refit(&moved).unwrap();
            assert_eq!(loaded.to_bytes(), bvh.to_bytes(), "{layout}");
        }
    }

    /// A small file of each layout family.
    fn small_files() -> Vec<(Layout, Vec<u8>)> {
        let tris = soup(40, 2);
        [
            Layout::Bvh8Dfs,
            Layout::Bvh2Compact,
            Layout::Bvh4Subtree,
            Layout::Bvh4Quant,
        ]
        .into_iter()
        .map(|l| {
            let bvh = Bvh::build(&tris, &BuildOptions::default().layout(l)).unwrap();
            (l, bvh.to_bytes())
        })
        .collect()
    }

    #[test]
    fn every_prefix_of_a_file_is_truncated() {
        for (layout, bytes) in small_files() {
            for n in 0..bytes.len() {
                match Bvh::from_bytes(&bytes[..n]) {
                    Err(LoadError::Truncated { have, .. }) => assert_eq!(have, n as u64),
                    other => panic!("{layout}: prefix {n}: {other:?}"),
                }
                assert!(
                    matches!(
                        Bvh::load(&mut &bytes[..n]),
                        Err(LoadError::Truncated { .. })
                    ),
                    "{layout}: prefix {n} through a reader"
                );
            }
            let mut longer = bytes.clone();
            longer.push(0);
            assert!(matches!(
                Bvh::from_bytes(&longer),
                Err(LoadError::TrailingBytes { extra: 1 })
            ));
        }
    }

    #[test]
    fn every_flipped_byte_is_an_error() {
        for (layout, bytes) in small_files() {
            for at in 0..bytes.len() {
                for mask in [0x01u8, 0x80, 0xff] {
                    let mut bad = bytes.clone();
                    bad[at] ^= mask;
                    assert!(
                        Bvh::from_bytes(&bad).is_err(),
                        "{layout}: byte {at} ^ {mask:#x} was accepted"
                    );
                }
            }
        }
    }

    #[test]
    fn magic_version_and_byte_order_are_checked_first() {
        let (_, bytes) = small_files().remove(0);
        let mut bad = bytes.clone();
        bad[0] = b'X';
        assert!(matches!(Bvh::from_bytes(&bad), Err(LoadError::BadMagic)));
        let mut newer = bytes.clone();
        newer[8..12].copy_from_slice(&7u32.to_le_bytes());
        assert!(matches!(
            Bvh::from_bytes(&newer),
            Err(LoadError::UnsupportedVersion {
                found: 7,
                supported: Bvh::FORMAT_VERSION
            })
        ));
        let mut swapped = bytes.clone();
        swapped[12..16].reverse();
        assert!(matches!(
            Bvh::from_bytes(&swapped),
            Err(LoadError::WrongEndianness)
        ));
        let mut layout = bytes.clone();
        layout[16] = 99;
        assert!(matches!(
            Bvh::from_bytes(&layout),
            Err(LoadError::BadHeader {
                field: "layout",
                value: 99
            })
        ));
        // Lengths whose bytes overflow are refused before anything is allocated.
        let mut huge = bytes;
        huge[96..104].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(matches!(
            Bvh::from_bytes(&huge),
            Err(LoadError::LengthOverflow { section: "nodes" })
        ));
        huge[96..104].copy_from_slice(&(u64::MAX / 512).to_le_bytes());
        assert!(matches!(
            Bvh::from_bytes(&huge),
            Err(LoadError::Truncated {
                section: "nodes",
                ..
            })
        ));
        assert!(matches!(
            Bvh::load(&mut &huge[..]),
            Err(LoadError::Truncated { .. })
        ));
    }

    /// A BVH of `layout` over a few triangles, changed by `edit` and saved with a valid
    /// checksum: what a hostile writer can make.
    fn crafted(layout: Layout, edit: impl FnOnce(&mut AnyLayout<Triangle>)) -> Vec<u8> {
        let tris = soup(200, 4);
        let mut bvh = Bvh::build(&tris, &BuildOptions::default().layout(layout)).unwrap();
        edit(&mut bvh.layout);
        bvh.to_bytes()
    }

    fn bvh2(l: &mut AnyLayout<Triangle>) -> &mut Bvh2<Triangle> {
        match l {
            AnyLayout::Bvh2(b) => b,
            _ => unreachable!(),
        }
    }

    fn bvh8(l: &mut AnyLayout<Triangle>) -> &mut Bvh8<Triangle> {
        match l {
            AnyLayout::Bvh8(b) => b,
            _ => unreachable!(),
        }
    }

    #[test]
    fn crafted_structures_are_typed_errors() {
        let load = |b: Vec<u8>| Bvh::from_bytes(&b).map(|_| ()).unwrap_err();
        // The root's right child is the root: a cycle.
        let e = load(crafted(Layout::Bvh2Dfs, |l| bvh2(l).nodes[0].link = 0));
        assert!(matches!(e, LoadError::NotATree { node: 0 }), "{e}");
        let e = load(crafted(Layout::Bvh2Dfs, |l| {
            bvh2(l).nodes[0].link = 1 << 20
        }));
        assert!(
            matches!(
                e,
                LoadError::ChildOutOfRange {
                    node: 0,
                    child: 1048576
                }
            ),
            "{e}"
        );
        // Both children of the root the same subtree: shared, not a tree.
        let e = load(crafted(Layout::Bvh2Bfs, |l| {
            let n = &mut bvh2(l).nodes[0];
            n.count = n.link;
        }));
        assert!(matches!(e, LoadError::NotATree { .. }), "{e}");
        // A compact block's height past any block.
        let e = load(crafted(Layout::Bvh2Compact, |l| {
            let b = bvh2(l);
            let i = (0..b.nodes.len())
                .find(|&i| !b.nodes[i].is_leaf() && b.nodes[i].count == 0)
                .unwrap();
            b.nodes[i].link = 40;
        }));
        assert!(
            matches!(e, LoadError::ChildOutOfRange { child: 40, .. }),
            "{e}"
        );
        let e = load(crafted(Layout::Bvh2Dfs, |l| {
            bvh2(l).nodes[2].max[1] = f32::NAN
        }));
        assert!(matches!(e, LoadError::NonFiniteBox { node: 2 }), "{e}");
        // An 8-wide inner slot pointing back at the root.
        let e = load(crafted(Layout::Bvh8Dfs, |l| {
            let n = &mut bvh8(l).nodes[0];
            let i = (0..8).find(|&i| n.count[i] == 0).unwrap();
            n.child[i] = 0;
        }));
        assert!(matches!(e, LoadError::NotATree { node: 0 }), "{e}");
        let e = load(crafted(Layout::Bvh8Dfs, |l| {
            let b = bvh8(l);
            let (j, i) = (0..b.nodes.len())
                .flat_map(|j| (0..8).map(move |i| (j, i)))
                .find(|&(j, i)| b.nodes[j].count[i] > Bvh8Node::LEAF)
                .unwrap();
            b.nodes[j].count[i] = Bvh8Node::LEAF | 1000;
        }));
        assert!(matches!(e, LoadError::PrimitiveOutOfRange { .. }), "{e}");
        // An inner slot with a count but no leaf flag: a child to the kernels, a leaf to
        // the refit (a fuzzer's find: the refit's leaf took past its primitives).
        let e = load(crafted(Layout::Bvh8Dfs, |l| {
            let n = &mut bvh8(l).nodes[0];
            let i = (0..8).find(|&i| n.count[i] == 0).unwrap();
            n.count[i] = 5;
        }));
        assert!(
            matches!(
                e,
                LoadError::SlotKind {
                    node: 0,
                    count: 5,
                    ..
                }
            ),
            "{e}"
        );
        // A lane naming another triangle than leaf order gives it.
        let e = load(crafted(Layout::Bvh8Dfs, |l| bvh8(l).tri4[3].id.swap(0, 1)));
        assert!(matches!(e, LoadError::GroupLane { group: 3, .. }), "{e}");
        let e = load(crafted(Layout::Bvh8Dfs, |l| bvh8(l).prim_ids[0] = 5000));
        assert!(
            matches!(
                e,
                LoadError::IdOutOfRange {
                    at: 0,
                    id: 5000,
                    ..
                }
            ),
            "{e}"
        );
    }

    #[test]
    fn a_chain_deeper_than_the_stacks_is_too_deep() {
        // Inner node i: left child i + 1, right child an empty leaf; the chain's end a leaf.
        let d = MAX_DEPTH + 1;
        let empty = bvh2_padding();
        let mut nodes = vec![empty; 2 * d + 1];
        for (i, node) in nodes.iter_mut().enumerate().take(d) {
            *node = Bvh2Node {
                min: [0.0; 3],
                link: i as u32 + 1,
                max: [1.0; 3],
                count: (d + 1 + i) as u32,
            };
        }
        let bvh = Bvh {
            layout: AnyLayout::Bvh2(Bvh2 {
                nodes,
                prims: Vec::new(),
                prim_ids: Vec::new(),
                mapping: Bvh2Mapping::BreadthFirst,
                inputs: Inputs { len: 0, held: 0 },
            }),
            frame: Frame::default(),
            bounds: Aabb::EMPTY,
        };
        let e = Bvh::from_bytes(&bvh.to_bytes()).map(|_| ()).unwrap_err();
        assert!(
            matches!(e, LoadError::TooDeep { depth, max: MAX_DEPTH } if depth == d),
            "{e}"
        );
    }

    #[test]
    fn the_streamed_checksum_is_the_checksum() {
        let data: Vec<u8> = (0..2 * BLOCK + 1000)
            .map(|i| (i * 13 % 251) as u8)
            .collect();
        for len in [
            0,
            1,
            7,
            31,
            32,
            33,
            100,
            BLOCK - 1,
            BLOCK,
            BLOCK + 5,
            data.len(),
        ] {
            let want = checksum(&data[..len]);
            for piece in [1, 5, 32, 100, 4096, BLOCK + 3] {
                let mut sum = StreamSum::new();
                data[..len].chunks(piece).for_each(|p| sum.put(p));
                assert_eq!(sum.finish(), want, "{len} bytes in pieces of {piece}");
            }
        }
    }

    /// A reader that hands out at most `n` bytes per read, to split the loader's reads.
    struct Dribble<'a>(&'a [u8], usize);

    impl Read for Dribble<'_> {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            let n = buf.len().min(self.1).min(self.0.len());
            buf[..n].copy_from_slice(&self.0[..n]);
            self.0 = &self.0[n..];
            Ok(n)
        }
    }

    #[test]
    fn a_reader_gets_what_bytes_get() {
        for (layout, bytes) in small_files() {
            let read = Bvh::load(&mut Dribble(&bytes, 7)).unwrap();
            assert_eq!(read.to_bytes(), bytes, "{layout}");
            for at in (0..bytes.len()).step_by(3) {
                let mut bad = bytes.clone();
                bad[at] ^= 0x40;
                let a = Bvh::from_bytes(&bad).map(|_| ()).unwrap_err();
                let b = Bvh::load(&mut Dribble(&bad, 61)).map(|_| ()).unwrap_err();
                // A reader stops where the header says the file ends: what follows is not
                // its business, so a shortened file reads as one with another checksum.
                if !matches!(a, LoadError::TrailingBytes { .. }) {
                    assert_eq!(format!("{a}"), format!("{b}"), "{layout}: byte {at}");
                }
            }
        }
    }

    #[test]
    fn the_checksum_sees_every_single_word_change() {
        let data: Vec<u8> = (0..3 * BLOCK / 2 + 40)
            .map(|i| (i * 7 % 251) as u8)
            .collect();
        let sum = checksum(&data);
        for at in (0..data.len()).step_by(997).chain([data.len() - 1]) {
            let mut d = data.clone();
            d[at] ^= 0x10;
            assert_ne!(checksum(&d), sum, "byte {at}");
        }
        assert_ne!(checksum(&data[..data.len() - 1]), sum);
    }
}
