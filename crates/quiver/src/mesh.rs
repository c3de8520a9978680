//! Indexed triangle meshes: positions plus index triples, read in place from the caller's
//! buffers.

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
        }
    }
}

impl std::error::Error for MeshError {}

/// A checked view of an indexed mesh: every index names a vertex.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Mesh<'a> {
    positions: &'a [[f32; 3]],
    indices: &'a [[u32; 3]],
}

impl<'a> Mesh<'a> {
    /// Checks every index against `positions`.
    pub fn new(positions: &'a [[f32; 3]], indices: &'a [[u32; 3]]) -> Result<Self, MeshError> {
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
        let [a, b, c] = self.indices[i as usize].map(|v| Vec3A::from(self.positions[v as usize]));
        Triangle::new(a, b, c)
    }

    /// One box per triangle, in parallel; NaN boxes for non-finite triangles, as
    /// [`crate::builders::prim_bounds`] gives.
    pub fn bounds(&self) -> Vec<Aabb> {
        use crate::primitive::Primitive;
        use rayon::prelude::*;
        (0..self.indices.len() as u32)
            .into_par_iter()
            .map(|i| Primitive::bounds(&self.triangle(i)))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_index_is_checked_and_named_in_the_error() {
        let p = [[0.0; 3]; 3];
        assert!(Mesh::new(&p, &[[0, 1, 2], [2, 1, 0]]).is_ok());
        assert!(Mesh::new(&p, &[]).is_ok());
        let e = Mesh::new(&p, &[[0, 1, 2], [0, 3, 1]]).unwrap_err();
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
        assert!(Mesh::new(&[], &[[0, 0, 0]]).is_err());
    }

    #[test]
    fn triangles_read_the_indexed_positions() {
        let p = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 2.0, 0.0],
            [f32::NAN, 0.0, 0.0],
        ];
        let m = Mesh::new(&p, &[[2, 0, 1], [0, 1, 3]]).unwrap();
        assert_eq!(
            m.triangle(0).v,
            [Vec3A::new(0.0, 2.0, 0.0), Vec3A::ZERO, Vec3A::X]
        );
        let b = m.bounds();
        assert_eq!(b[0], Aabb::new(Vec3A::ZERO, Vec3A::new(1.0, 2.0, 0.0)));
        assert!(
            !b[1].is_finite(),
            "a NaN vertex gives a NaN box, which the build drops"
        );
    }
}
