//! Wavefront OBJ through tobj: every face triangulated, one object per triangle.

use super::{Camera, Scene, SceneError};
use glam::Vec3A;
use quiver::geometry::{Aabb, Triangle};
use std::path::Path;

pub(super) fn load(path: &Path) -> Result<Scene, SceneError> {
    let err = |message: String| SceneError::File {
        path: path.into(),
        message,
    };
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _materials) =
        tobj::load_obj(path, &opts).map_err(|e| err(format!("cannot load OBJ: {e}")))?;
    let mut tris = Vec::new();
    for m in &models {
        let pos = &m.mesh.positions;
        let vertex = |i: u32| -> Result<Vec3A, SceneError> {
            let i = i as usize;
            pos.get(3 * i..3 * i + 3)
                .map(Vec3A::from_slice)
                .ok_or_else(|| {
                    err(format!(
                        "model '{}': vertex index {} out of range ({} vertices)",
                        m.name,
                        i + 1,
                        pos.len() / 3
                    ))
                })
        };
        for f in m.mesh.indices.chunks_exact(3) {
            tris.push(Triangle::new(vertex(f[0])?, vertex(f[1])?, vertex(f[2])?));
        }
    }
    let bounds = tris.iter().fold(Aabb::EMPTY, |b, t| b.union(&t.bounds()));
    Ok(Scene::from_triangles(
        path.display().to_string(),
        tris,
        Camera::framing(&bounds),
        vec![bounds.max + bounds.extent()],
        Vec3A::splat(0.2),
    ))
}
