//! Indexed triangle meshes: positions plus index triples, read in place from the caller's
//! buffers (packed `[f32; 3]` positions, or positions inside a larger vertex struct read
//! through a stride, [`Positions`]).

use crate::geometry::{Aabb, Triangle};
use glam::Vec3A;
use std::fmt;

/// Why an indexed mesh cannot be built.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum MeshError {
    /// An index names a vertex past the end of the position buffer.
    IndexOutOfRange {
        /// The triangle (position in the index buffer).
        triangle: usize,
        /// Which of its three indices (0, 1 or 2).
        corner: usize,
        /// The index found there.
        index: u32,
        /// The number of vertices in the position buffer.
        vertices: usize,
    },
    /// More triangles than hit records can number (`u32` primitive indices).
    TooManyTriangles {
        /// The number of index triples given.
        triangles: usize,
    },
    /// A strided position buffer whose layout cannot hold a position: the stride is shorter
    /// than the 12 bytes of three `f32`, or the position at `offset` runs past the stride.
    Stride {
        /// The byte offset of the position inside each vertex.
        offset: usize,
        /// The bytes from one vertex to the next.
        stride: usize,
    },
}

impl fmt::Display for MeshError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MeshError::IndexOutOfRange {
                triangle,
                corner,
                index,
                vertices,
            } => write!(
                f,
                "triangle {triangle}, index {corner}: vertex {index} does not exist (the mesh has \
                 {vertices} vertices)"
            ),
            MeshError::TooManyTriangles { triangles } => write!(
                f,
                "{triangles} triangles: at most {} can be numbered by a hit",
                u32::MAX
            ),
            MeshError::Stride { offset, stride } => write!(
                f,
                "positions at byte offset {offset} with a stride of {stride} bytes: a position \
                 (three f32, 12 bytes) must fit inside one stride (offset + 12 <= stride)"
            ),
        }
    }
}

impl std::error::Error for MeshError {}

/// A mesh's vertex positions, read in place: packed `[f32; 3]` triples, or the three `f32`
/// at a byte offset inside each vertex of an interleaved buffer (positions beside normals,
/// texture coordinates, colours), so an embedder's vertex buffer is used without a copy.
///
/// Packed positions convert with `into()` (every mesh function takes `impl Into<Positions>`),
/// so `&[[f32; 3]]`, `&Vec<[f32; 3]>` and `&[[f32; 3]; N]` are passed as they are.
///
/// ```
/// use quiver_rt::{bytemuck, Bvh, Positions, Ray, RayQuery};
/// use glam::Vec3A;
/// #[repr(C)]
/// #[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
/// struct Vertex {
///     uv: [f32; 2],
///     position: [f32; 3],
///     normal: [f32; 3],
/// }
/// let v = |x: f32, y: f32| Vertex { uv: [x, y], position: [x, y, 0.0], normal: [0.0, 0.0, 1.0] };
/// let vertices = [v(0.0, 0.0), v(1.0, 0.0), v(0.0, 1.0)];
/// let positions = Positions::of_vertices(&vertices, std::mem::offset_of!(Vertex, position)).unwrap();
/// let bvh = Bvh::from_mesh(positions, &[[0, 1, 2]]).unwrap();
/// let hit = bvh.closest_hit(&Ray::new(Vec3A::new(0.25, 0.25, 1.0), -Vec3A::Z)).unwrap();
/// assert_eq!((hit.prim, hit.t), (0, 1.0));
/// // The same positions packed give the same BVH.
/// let packed = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
/// assert_eq!(Bvh::from_mesh(&packed, &[[0, 1, 2]]).unwrap().closest_hit(&Ray::new(Vec3A::new(0.25, 0.25, 1.0), -Vec3A::Z)), Some(hit));
/// // A position that does not fit inside the vertex is an error, not a wrong read.
/// assert!(Positions::strided(bytemuck::cast_slice(&vertices), 28, 32).is_err());
/// ```
#[derive(Clone, Copy, Debug)]
pub struct Positions<'a>(Layout<'a>);

#[derive(Clone, Copy, Debug)]
enum Layout<'a> {
    Packed(&'a [[f32; 3]]),
    Strided {
        bytes: &'a [u8],
        offset: usize,
        stride: usize,
        count: usize,
    },
}

impl<'a> Positions<'a> {
    /// Positions of packed triples.
    pub fn packed(positions: &'a [[f32; 3]]) -> Self {
        Positions(Layout::Packed(positions))
    }

    /// Vertex `i`'s position is the three native-endian `f32` at byte `offset + i * stride`
    /// of `bytes` (no alignment required). The buffer holds as many vertices as have their
    /// position inside it (a last vertex may be cut short after its position).
    ///
    /// # Errors
    /// [`MeshError::Stride`] when a position cannot fit inside one stride
    /// (`offset + 12 > stride`).
    pub fn strided(bytes: &'a [u8], offset: usize, stride: usize) -> Result<Self, MeshError> {
        if offset.checked_add(12).is_none_or(|end| end > stride) {
            return Err(MeshError::Stride { offset, stride });
        }
        let count = match bytes.len().checked_sub(offset + 12) {
            Some(rest) => rest / stride + 1,
            None => 0,
        };
        Ok(Positions(Layout::Strided {
            bytes,
            offset,
            stride,
            count,
        }))
    }

    /// The positions inside an array of vertex structs: the three `f32` at byte `offset`
    /// of each (`std::mem::offset_of!(Vertex, position)`), the stride the struct's size.
    ///
    /// # Errors
    /// As [`Positions::strided`].
    pub fn of_vertices<T: bytemuck::Pod>(
        vertices: &'a [T],
        offset: usize,
    ) -> Result<Self, MeshError> {
        Self::strided(
            bytemuck::cast_slice(vertices),
            offset,
            std::mem::size_of::<T>(),
        )
    }

    /// The number of vertices.
    pub fn len(&self) -> usize {
        match self.0 {
            Layout::Packed(p) => p.len(),
            Layout::Strided { count, .. } => count,
        }
    }

    /// Whether there are no vertices.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Vertex `i`'s position; `i` below [`Positions::len`].
    #[inline]
    fn get(&self, i: usize) -> Vec3A {
        match self.0 {
            Layout::Packed(p) => Vec3A::from(p[i]),
            Layout::Strided {
                bytes,
                offset,
                stride,
                ..
            } => {
                let at = offset + i * stride;
                Vec3A::from(bytemuck::pod_read_unaligned::<[f32; 3]>(
                    &bytes[at..at + 12],
                ))
            }
        }
    }
}

impl<'a> From<&'a [[f32; 3]]> for Positions<'a> {
    fn from(p: &'a [[f32; 3]]) -> Self {
        Positions::packed(p)
    }
}

impl<'a> From<&'a Vec<[f32; 3]>> for Positions<'a> {
    fn from(p: &'a Vec<[f32; 3]>) -> Self {
        Positions::packed(p)
    }
}

impl<'a, const N: usize> From<&'a [[f32; 3]; N]> for Positions<'a> {
    fn from(p: &'a [[f32; 3]; N]) -> Self {
        Positions::packed(p)
    }
}

/// A checked view of an indexed mesh: every index names a vertex.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Mesh<'a> {
    positions: Positions<'a>,
    indices: &'a [[u32; 3]],
}

impl<'a> Mesh<'a> {
    /// Checks every index against `positions`.
    pub fn new(positions: Positions<'a>, indices: &'a [[u32; 3]]) -> Result<Self, MeshError> {
        // `u32::MAX` stays free: it marks "no primitive" in a closest-hit search.
        if indices.len() > u32::MAX as usize {
            return Err(MeshError::TooManyTriangles {
                triangles: indices.len(),
            });
        }
        for (triangle, tri) in indices.iter().enumerate() {
            for (corner, &index) in tri.iter().enumerate() {
                if index as usize >= positions.len() {
                    return Err(MeshError::IndexOutOfRange {
                        triangle,
                        corner,
                        index,
                        vertices: positions.len(),
                    });
                }
            }
        }
        Ok(Mesh { positions, indices })
    }

    /// Triangle `i`.
    #[inline]
    pub fn triangle(&self, i: u32) -> Triangle {
        let [a, b, c] = self.indices[i as usize].map(|v| self.positions.get(v as usize));
        Triangle::new(a, b, c)
    }

    /// One box per triangle, in parallel (NaN boxes for non-finite triangles, as
    /// [`crate::builders::prim_bounds`] gives), and the frame the build takes them in.
    pub fn bounds(&self) -> (Vec<Aabb>, crate::frame::Frame) {
        crate::frame::Frame::bounds(self.indices.len(), |i| self.triangle(i as u32).bounds())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_index_is_checked_and_named_in_the_error() {
        let p = [[0.0; 3]; 3];
        assert!(Mesh::new((&p).into(), &[[0, 1, 2], [2, 1, 0]]).is_ok());
        assert!(Mesh::new((&p).into(), &[]).is_ok());
        let e = Mesh::new((&p).into(), &[[0, 1, 2], [0, 3, 1]]).unwrap_err();
        assert_eq!(
            e,
            MeshError::IndexOutOfRange {
                triangle: 1,
                corner: 1,
                index: 3,
                vertices: 3
            }
        );
        assert_eq!(
            e.to_string(),
            "triangle 1, index 1: vertex 3 does not exist (the mesh has 3 vertices)"
        );
        assert!(Mesh::new(Positions::packed(&[]), &[[0, 0, 0]]).is_err());
    }

    #[test]
    fn triangles_read_the_indexed_positions() {
        let p = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 2.0, 0.0],
            [f32::NAN, 0.0, 0.0],
        ];
        let m = Mesh::new((&p).into(), &[[2, 0, 1], [0, 1, 3]]).unwrap();
        assert_eq!(
            m.triangle(0).v,
            [Vec3A::new(0.0, 2.0, 0.0), Vec3A::ZERO, Vec3A::X]
        );
        let b = m.bounds().0;
        assert_eq!(b[0], Aabb::new(Vec3A::ZERO, Vec3A::new(1.0, 2.0, 0.0)));
        assert!(
            !b[1].is_finite(),
            "a NaN vertex gives a NaN box, which the build drops"
        );
    }

    #[test]
    fn strided_positions_read_what_packed_ones_hold() {
        // Five vertices of 9 floats (36 bytes), the position at byte 13 (unaligned), with a
        // last vertex cut short after its position.
        let packed: Vec<[f32; 3]> = (0..5)
            .map(|i| [i as f32 + 0.5, -(i as f32) * 3.25, 1e-3 * i as f32])
            .collect();
        let mut bytes = vec![0xa5u8; 5 * 36];
        for (i, p) in packed.iter().enumerate() {
            let at = 13 + 36 * i;
            bytes[at..at + 12].copy_from_slice(bytemuck::cast_slice(p));
        }
        bytes.truncate(4 * 36 + 13 + 12);
        let strided = Positions::strided(&bytes, 13, 36).unwrap();
        assert_eq!(strided.len(), 5);
        let indices = [[0, 1, 2], [4, 3, 0], [2, 4, 1]];
        let a = Mesh::new(strided, &indices).unwrap();
        let b = Mesh::new((&packed).into(), &indices).unwrap();
        for i in 0..3 {
            assert_eq!(a.triangle(i).v, b.triangle(i).v);
        }
        // One byte less and the fifth position is no longer there.
        let short = Positions::strided(&bytes[..bytes.len() - 1], 13, 36).unwrap();
        assert_eq!(short.len(), 4);
        assert_eq!(
            Mesh::new(short, &indices).unwrap_err(),
            MeshError::IndexOutOfRange {
                triangle: 1,
                corner: 0,
                index: 4,
                vertices: 4
            }
        );
        assert!(Positions::strided(&bytes[..24], 13, 36).unwrap().is_empty());
    }

    #[test]
    fn a_stride_that_cannot_hold_a_position_is_refused() {
        let bytes = [0u8; 64];
        for (offset, stride) in [(0, 11), (21, 32), (usize::MAX, 16), (0, 0)] {
            let e = Positions::strided(&bytes, offset, stride).unwrap_err();
            assert_eq!(e, MeshError::Stride { offset, stride });
        }
        assert!(Positions::strided(&bytes, 20, 32).is_ok());
        assert_eq!(
            MeshError::Stride {
                offset: 21,
                stride: 32
            }
            .to_string(),
            "positions at byte offset 21 with a stride of 32 bytes: a position (three f32, 12 \
             bytes) must fit inside one stride (offset + 12 <= stride)"
        );
    }
}
