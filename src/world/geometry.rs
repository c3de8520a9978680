//! [`Geometry`]: one geometry's BVH and its primitives, stored once however often placed.

use crate::geometry::{Aabb, PrimHit, Triangle};
use crate::layout::Footprint;
use crate::primitive::Primitive;
use crate::Bvh;

use super::MovingTriangles;
use glam::Vec3A;

/// The BVH of one geometry, with its primitives in input order for normals.
#[derive(Clone, Debug)]
pub enum Geometry<P = Triangle> {
    /// Triangles (from a mesh or a slice), on the triangle fast path.
    Triangles(Bvh<Triangle>, Vec<Triangle>),
    /// Primitives of the world's own type.
    Prims(Bvh<P>, Vec<P>),
    /// A deforming triangle mesh: its triangles at evenly spaced times, met by a ray at its
    /// time (see [`MovingTriangles`]).
    MovingTriangles(MovingTriangles),
}

impl<P: Primitive> Geometry<P> {
    /// The box around every primitive, in object space.
    pub fn bounds(&self) -> Aabb {
        match self {
            Geometry::Triangles(b, _) => b.bounds(),
            Geometry::Prims(b, _) => b.bounds(),
            Geometry::MovingTriangles(m) => m.bounds(),
        }
    }

    /// Primitives in the geometry.
    pub fn len(&self) -> usize {
        match self {
            Geometry::Triangles(_, t) => t.len(),
            Geometry::Prims(_, p) => p.len(),
            Geometry::MovingTriangles(m) => m.len(),
        }
    }

    /// True for a geometry of no primitives.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// What the BVH occupies (nodes and the leaf data its kernels read) and the primitives
    /// kept in input order (for normals).
    pub fn footprint(&self) -> Footprint {
        let (f, kept) = match self {
            Geometry::Triangles(b, t) => (b.footprint(), std::mem::size_of_val(t.as_slice())),
            Geometry::Prims(b, p) => (b.footprint(), std::mem::size_of_val(p.as_slice())),
            // Its steps are what its walks read: counted in its footprint already.
            Geometry::MovingTriangles(m) => (m.footprint(), 0),
        };
        Footprint {
            bytes: f.bytes + kept,
            kept: f.kept + kept,
            ..f
        }
    }

    /// The object-space geometric normal of primitive `prim` at `hit` of a ray at shutter
    /// time `time` (a moving mesh's triangle then), if its type has one.
    pub(super) fn normal(&self, prim: u32, at: Vec3A, hit: &PrimHit, time: f32) -> Option<Vec3A> {
        match self {
            Geometry::Triangles(_, t) => t.get(prim as usize)?.geometric_normal(at, hit),
            Geometry::Prims(_, p) => p.get(prim as usize)?.geometric_normal(at, hit),
            Geometry::MovingTriangles(m) => m.triangle_at(prim, time)?.geometric_normal(at, hit),
        }
    }
}
