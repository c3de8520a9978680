//! `qv_bvh_*`: a BVH over one indexed triangle mesh.

use crate::buffers::{bad_mesh, input, output, read_indices, read_vertices};
use crate::error::{free_handle, guard, non_null, Failure, QvStatus};
use crate::files::{self, path_of};
use crate::trace;
use crate::types::{options_of, QvBuildOptions, QvHit, QvPointHit, QvRay};
use quiver_rt::glam::Vec3A;
use quiver_rt::{BuildError, Bvh};
use std::ffi::{c_char, c_int};

/// A BVH over an indexed triangle mesh (opaque to C), with the mesh's index buffer kept for
/// refits.
pub struct QvBvh {
    bvh: Bvh,
    /// The triangles' vertex indices, for `qv_bvh_refit`; `None` for a BVH loaded from a
    /// file (the file format holds the triangles, not the indices).
    indices: Option<Vec<[u32; 3]>>,
}

impl trace::Traced for QvBvh {
    const ARGUMENT: &'static str = "bvh";
    type Scene = Bvh;
    fn scene(&self) -> &Bvh {
        &self.bvh
    }
    fn to_c(hit: Option<quiver_rt::Hit>) -> QvHit {
        QvHit::of_bvh(hit)
    }
}

/// The BVH behind handle `bvh`.
///
/// # Safety
/// `bvh` is NULL or a handle from `qv_bvh_build_indexed` or `qv_bvh_load` not yet freed, that
/// no other thread changes during the call.
unsafe fn get<'a>(bvh: *const QvBvh) -> Result<&'a QvBvh, Failure> {
    non_null(bvh, "bvh")?;
    // SAFETY: not NULL (checked); the caller promised a live handle, which is a `Box<QvBvh>`
    // turned into a raw pointer, not changed meanwhile.
    Ok(unsafe { &*bvh })
}

/// Refuses a NULL `out`; else writes NULL to it first, so a call refused later leaves no
/// stale handle behind.
///
/// # Safety
/// `out` is NULL or valid for one pointer write.
unsafe fn clear_out<T>(out: *mut *mut T) -> Result<(), Failure> {
    non_null(out, "out")?;
    // SAFETY: not NULL (checked), and the caller promised it is writable.
    unsafe { out.write(std::ptr::null_mut()) };
    Ok(())
}

/// Builds a BVH over an indexed triangle mesh: vertex `i`'s position is the three floats at
/// byte `i * vertex_stride_bytes` of `vertices`, triangle `t`'s three vertex indices the three
/// `uint32_t` at byte `t * index_stride_bytes` of `indices`. The buffers are copied; hits
/// name triangle `t`. On success `*out` is the new handle (free it with `qv_bvh_free`), else
/// NULL. `qv_bvh_build_indexed_with` with the default options.
///
/// # Safety
/// `vertices` and `indices` are NULL or readable for their counts and strides; `out` is NULL
/// or writable (see `quiver.h`).
#[no_mangle]
pub unsafe extern "C" fn qv_bvh_build_indexed(
    vertices: *const f32,
    vertex_count: usize,
    vertex_stride_bytes: usize,
    indices: *const u32,
    triangle_count: usize,
    index_stride_bytes: usize,
    out: *mut *mut QvBvh,
) -> QvStatus {
    let mesh = Mesh {
        vertices,
        vertex_count,
        vertex_stride_bytes,
        indices,
        triangle_count,
        index_stride_bytes,
    };
    // SAFETY: the caller's contract, which `build_indexed` asks; no options.
    unsafe { build_indexed("qv_bvh_build_indexed", mesh, std::ptr::null(), out) }
}

/// As `qv_bvh_build_indexed`, built with `*options` (NULL: the defaults): a preset
/// (`options.quality`) and a layout (`options.layout`, NULL for the preset's).
///
/// # Safety
/// As `qv_bvh_build_indexed`; `options` NULL or readable, its `layout` NULL or a
/// NUL-terminated string.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn qv_bvh_build_indexed_with(
    vertices: *const f32,
    vertex_count: usize,
    vertex_stride_bytes: usize,
    indices: *const u32,
    triangle_count: usize,
    index_stride_bytes: usize,
    options: *const QvBuildOptions,
    out: *mut *mut QvBvh,
) -> QvStatus {
    let mesh = Mesh {
        vertices,
        vertex_count,
        vertex_stride_bytes,
        indices,
        triangle_count,
        index_stride_bytes,
    };
    // SAFETY: the caller's contract, which `build_indexed` asks.
    unsafe { build_indexed("qv_bvh_build_indexed_with", mesh, options, out) }
}

/// A caller's indexed mesh: its buffers, counts and strides, as the build functions take them.
#[derive(Clone, Copy)]
pub(crate) struct Mesh {
    pub vertices: *const f32,
    pub vertex_count: usize,
    pub vertex_stride_bytes: usize,
    pub indices: *const u32,
    pub triangle_count: usize,
    pub index_stride_bytes: usize,
}

/// A mesh's vertex positions and index triples, read from the caller's buffers.
pub(crate) type MeshData = (Vec<[f32; 3]>, Vec<[u32; 3]>);

impl Mesh {
    /// The positions and index triples, copied and checked (strides, indices, finite
    /// coordinates).
    ///
    /// # Safety
    /// The buffers are NULL or readable for their counts and strides.
    pub(crate) unsafe fn read(self) -> Result<MeshData, Failure> {
        // SAFETY: the caller's contract for the buffers, passed on unchanged.
        let positions =
            unsafe { read_vertices(self.vertices, self.vertex_count, self.vertex_stride_bytes) }?;
        // SAFETY: as above.
        let tris = unsafe {
            read_indices(
                self.indices,
                self.triangle_count,
                self.index_stride_bytes,
                self.vertex_count,
            )
        }?;
        Ok((positions, tris))
    }
}

/// The body of exported function `name`: the BVH over `mesh` built with `options` into
/// `*out`.
///
/// # Safety
/// `mesh`'s buffers NULL or readable for their counts and strides; `options` NULL or a
/// readable `QvBuildOptions` whose `layout` is NULL or NUL-terminated; `out` NULL or
/// writable.
unsafe fn build_indexed(
    name: &str,
    mesh: Mesh,
    options: *const QvBuildOptions,
    out: *mut *mut QvBvh,
) -> QvStatus {
    guard(name, || {
        // SAFETY: the caller's contract for `out`.
        unsafe { clear_out(out) }?;
        // SAFETY: the caller's contract for `options`.
        let options = unsafe { options_of(options) }?;
        // SAFETY: the caller's contract for the buffers.
        let (positions, tris) = unsafe { mesh.read() }?;
        let bvh = Bvh::build_mesh(&positions, &tris, &options).map_err(|e| match e {
            BuildError::Mesh(e) => bad_mesh("indices", e),
            e => Failure::new(QvStatus::InvalidArgument, format!("options: {e}")),
        })?;
        let handle = Box::new(QvBvh {
            bvh,
            indices: Some(tris),
        });
        // SAFETY: `out` is not NULL and writable (checked by `clear_out`, the caller's
        // contract).
        unsafe { out.write(Box::into_raw(handle)) };
        Ok(())
    })
}

/// Frees a BVH; NULL is ignored.
///
/// # Safety
/// `bvh` is NULL or a live handle that no other thread uses, and is not used again.
#[no_mangle]
pub unsafe extern "C" fn qv_bvh_free(bvh: *mut QvBvh) {
    // SAFETY: the caller's contract.
    unsafe { free_handle("qv_bvh_free", bvh) }
}

/// The closest hit of `*ray` into `*hit` (the miss record when nothing is hit).
///
/// # Safety
/// `bvh` a live handle or NULL; `ray` readable and `hit` writable, or NULL.
#[no_mangle]
pub unsafe extern "C" fn qv_bvh_closest_hit(
    bvh: *const QvBvh,
    ray: *const QvRay,
    hit: *mut QvHit,
) -> QvStatus {
    // SAFETY: the caller's contract, which `trace::closest_hit` asks.
    unsafe { trace::closest_hit("qv_bvh_closest_hit", bvh, ray, hit) }
}

/// Whether anything is hit within `*ray`'s interval: `*occluded` is 1 or 0.
///
/// # Safety
/// `bvh` a live handle or NULL; `ray` readable and `occluded` writable, or NULL.
#[no_mangle]
pub unsafe extern "C" fn qv_bvh_any_hit(
    bvh: *const QvBvh,
    ray: *const QvRay,
    occluded: *mut c_int,
) -> QvStatus {
    // SAFETY: the caller's contract, which `trace::any_hit` asks.
    unsafe { trace::any_hit("qv_bvh_any_hit", bvh, ray, occluded) }
}

/// The closest hits of `n` rays into `hits[0..n]`, traced in parallel.
///
/// # Safety
/// `bvh` a live handle or NULL; `rays` readable and `hits` writable for `n` elements, not
/// overlapping, or NULL.
#[no_mangle]
pub unsafe extern "C" fn qv_bvh_closest_hits(
    bvh: *const QvBvh,
    rays: *const QvRay,
    n: usize,
    hits: *mut QvHit,
) -> QvStatus {
    // SAFETY: the caller's contract, which `trace::closest_hits` asks.
    unsafe { trace::closest_hits("qv_bvh_closest_hits", bvh, rays, n, hits) }
}

/// Whether each of `n` rays hits anything: `occluded[i]` is 1 or 0; traced in parallel.
///
/// # Safety
/// `bvh` a live handle or NULL; `rays` readable and `occluded` writable for `n` elements, not
/// overlapping, or NULL.
#[no_mangle]
pub unsafe extern "C" fn qv_bvh_any_hits(
    bvh: *const QvBvh,
    rays: *const QvRay,
    n: usize,
    occluded: *mut u8,
) -> QvStatus {
    // SAFETY: the caller's contract, which `trace::any_hits` asks.
    unsafe { trace::any_hits("qv_bvh_any_hits", bvh, rays, n, occluded) }
}

/// Refits the BVH to new vertex positions for the same triangles (the index buffer given to
/// `qv_bvh_build_indexed`, kept since): the tree stays, its boxes follow the vertices.
///
/// # Safety
/// `bvh` a live handle or NULL, used by no other thread during the call; `vertices` NULL or
/// readable for `vertex_count` vertices `vertex_stride_bytes` apart.
#[no_mangle]
pub unsafe extern "C" fn qv_bvh_refit(
    bvh: *mut QvBvh,
    vertices: *const f32,
    vertex_count: usize,
    vertex_stride_bytes: usize,
) -> QvStatus {
    guard("qv_bvh_refit", || {
        non_null(bvh, "bvh")?;
        // SAFETY: not NULL (checked); a live handle used by no other thread (the caller's
        // contract), so this is the only reference.
        let b = unsafe { &mut *bvh };
        let Some(indices) = &b.indices else {
            return Err(Failure::new(
                QvStatus::InvalidArgument,
                "bvh: loaded from a file, it keeps no index buffer to refit with (build it \
                 with qv_bvh_build_indexed)",
            ));
        };
        // SAFETY: the caller's contract for the buffer.
        let positions = unsafe { read_vertices(vertices, vertex_count, vertex_stride_bytes) }?;
        b.bvh
            .refit_mesh(&positions, indices)
            .map_err(|e| Failure::new(QvStatus::BadMesh, format!("vertices: {e}")))
    })
}

/// The point of the BVH's triangles nearest `point` within `max_distance` (inclusive;
/// `INFINITY` for any distance) into `*hit` (the miss record when none lies that near, or
/// for a non-finite point or a NaN or negative distance).
///
/// # Safety
/// `bvh` a live handle or NULL; `point` readable for three floats and `hit` writable, or
/// NULL.
#[no_mangle]
pub unsafe extern "C" fn qv_bvh_closest_point(
    bvh: *const QvBvh,
    point: *const f32,
    max_distance: f32,
    hit: *mut QvPointHit,
) -> QvStatus {
    guard("qv_bvh_closest_point", || {
        // SAFETY: the caller's contract for each pointer: three floats at `point`, one hit.
        let (b, point, hit) =
            unsafe { (get(bvh)?, input(point, 3, "point")?, output(hit, 1, "hit")?) };
        let p = Vec3A::new(point[0], point[1], point[2]);
        hit[0].write(QvPointHit::of(b.bvh.closest_point(p, max_distance)));
        Ok(())
    })
}

/// Writes the BVH to the file `path` (created or replaced, all or nothing) in quiver's file format.
///
/// # Safety
/// `bvh` a live handle or NULL; `path` NULL or a NUL-terminated string.
#[no_mangle]
pub unsafe extern "C" fn qv_bvh_save(bvh: *const QvBvh, path: *const c_char) -> QvStatus {
    guard("qv_bvh_save", || {
        // SAFETY: the caller's contract for each pointer.
        let (b, path) = unsafe { (get(bvh)?, path_of(path)?) };
        files::save(&path, |file| b.bvh.save(file))
    })
}

/// Reads a BVH that `qv_bvh_save` wrote from the file `path`, checked completely before it
/// is returned. On success `*out` is the new handle (free it with `qv_bvh_free`), else NULL.
///
/// # Safety
/// `path` NULL or a NUL-terminated string; `out` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn qv_bvh_load(path: *const c_char, out: *mut *mut QvBvh) -> QvStatus {
    guard("qv_bvh_load", || {
        // SAFETY: the caller's contract for each pointer.
        let path = unsafe {
            clear_out(out)?;
            path_of(path)?
        };
        let bvh = files::load(&path, Bvh::from_bytes)?;
        let handle = Box::new(QvBvh { bvh, indices: None });
        // SAFETY: `out` is not NULL and writable (checked by `clear_out`, the caller's
        // contract).
        unsafe { out.write(Box::into_raw(handle)) };
        Ok(())
    })
}

/// The bytes the BVH holds into `*bytes`: its nodes, its leaves' triangles and their ids, and
/// what it keeps for refits (the core's `Footprint::kept`); not the index buffer kept for
/// `qv_bvh_refit` nor the handle itself.
///
/// # Safety
/// `bvh` a live handle or NULL; `bytes` writable or NULL.
#[no_mangle]
pub unsafe extern "C" fn qv_bvh_footprint(bvh: *const QvBvh, bytes: *mut usize) -> QvStatus {
    guard("qv_bvh_footprint", || {
        // SAFETY: the caller's contract for each pointer.
        let (b, bytes) = unsafe { (get(bvh)?, output(bytes, 1, "bytes")?) };
        bytes[0].write(b.bvh.footprint().kept);
        Ok(())
    })
}
