//! `qv_world_*`: instanced worlds, from a builder (meshes, instances, filters) to queries and
//! edits.

use crate::buffers::{bad_mesh, input, output, read_indices, read_vertices};
use crate::bvh::Mesh;
use crate::error::{free_handle, guard, non_null, Failure, QvStatus};
use crate::files::{self, path_of};
use crate::trace;
use crate::types::{
    affine_of_rows, options_of, QvBuildOptions, QvFilterFn, QvHit, QvPointHit, QvRay,
};
use quiver_rt::glam::{Affine3A, Vec3A};
use quiver_rt::world::{invert, Geometry, WorldEdit, WorldPointHit, MAX_MOTION_KEYS};
use quiver_rt::{
    GeometryId, Instance, InstanceId, Motion, Triangle, World, WorldBuilder, WorldError, WorldHit,
};
use std::ffi::{c_char, c_int, c_void};

/// A world being collected: meshes, instances, filters (opaque to C).
pub struct QvWorldBuilder {
    builder: WorldBuilder,
    /// Each geometry's index buffer (a mesh's) or `None` (a moving mesh's), in the order
    /// added: what the built world keeps for `qv_world_refit_mesh`, and how many geometries
    /// there are, to refuse an instance of a missing one at once.
    indices: Vec<Option<Vec<[u32; 3]>>>,
}

impl QvWorldBuilder {
    /// The geometries added so far.
    fn geometries(&self) -> u32 {
        // At most `u32::MAX - 1`: the add functions refuse more.
        self.indices.len() as u32
    }
}

/// A built world (opaque to C), with its mesh geometries' index buffers kept for refits.
pub struct QvWorld {
    world: World,
    /// Geometry `g`'s index buffer at `g`, for `qv_world_refit_mesh`: `None` (or past the
    /// end) for a moving mesh and for every geometry of a world loaded from a file (the file
    /// format holds triangles, not indices).
    indices: Vec<Option<Vec<[u32; 3]>>>,
}

/// A filter's `user` pointer, shared by every thread that queries the world.
#[derive(Clone, Copy)]
struct SharedUser(*mut c_void);

// SAFETY: the C caller of `qv_world_builder_set_filter` accepted (quiver.h) that the callback
// is called from any thread, several at once, with this same pointer, and that whatever it
// points to is safe to use that way (read-only, or synchronised by the caller). The pointer is
// only ever passed back to that callback; Rust never reads through it.
unsafe impl Send for SharedUser {}
// SAFETY: as for `Send`: sharing the pointer between threads is what the caller agreed to.
unsafe impl Sync for SharedUser {}

impl SharedUser {
    /// The pointer (a method, so closures capture the whole `SharedUser`, not the raw field).
    fn get(self) -> *mut c_void {
        self.0
    }
}

/// The builder behind a handle.
///
/// # Safety
/// `b` is NULL or a live builder handle no other thread uses during the call.
unsafe fn builder_mut<'a>(b: *mut QvWorldBuilder) -> Result<&'a mut QvWorldBuilder, Failure> {
    non_null(b, "builder")?;
    // SAFETY: not NULL (checked); a live handle (a `Box<QvWorldBuilder>` as a raw pointer)
    // used by no other thread, so this is the only reference (the caller's contract).
    Ok(unsafe { &mut *b })
}

impl trace::Traced for QvWorld {
    const ARGUMENT: &'static str = "world";
    type Scene = World;
    fn scene(&self) -> &World {
        &self.world
    }
    fn to_c(hit: Option<WorldHit>) -> QvHit {
        QvHit::of_world(hit)
    }
}

/// The world behind a handle, to edit.
///
/// # Safety
/// `w` is NULL or a live world handle no other thread uses during the call.
unsafe fn world_mut<'a>(w: *mut QvWorld) -> Result<&'a mut World, Failure> {
    // SAFETY: the caller's contract.
    Ok(unsafe { &mut handle_mut(w)?.world })
}

/// The handle `w`, to edit its world and what it keeps beside it.
///
/// # Safety
/// As [`world_mut`].
unsafe fn handle_mut<'a>(w: *mut QvWorld) -> Result<&'a mut QvWorld, Failure> {
    non_null(w, "world")?;
    // SAFETY: not NULL (checked); a live handle used by no other thread (the caller's
    // contract), so this is the only reference.
    Ok(unsafe { &mut *w })
}

/// The status and message for a world's refusal.
fn world_failure(e: WorldError) -> Failure {
    let status = match e {
        WorldError::Mesh { .. } | WorldError::Refit { .. } => QvStatus::BadMesh,
        _ => QvStatus::InvalidArgument,
    };
    Failure::new(status, e)
}

/// The transform at `transform` (12 floats, row-major 3×4), checked as a world checks an
/// instance's: finite and invertible in f32.
///
/// # Safety
/// `transform` is NULL or readable for 12 floats.
unsafe fn transform_of(transform: *const f32) -> Result<Affine3A, Failure> {
    // SAFETY: the caller's contract: 12 floats.
    let m = unsafe { input(transform, 12, "transform") }?;
    let m = affine_of_rows(m.try_into().expect("12 floats"));
    invert(&m)
        .map_err(|why| Failure::new(QvStatus::InvalidArgument, format!("transform: {why}")))?;
    Ok(m)
}

/// The motion through the `key_count` keys at `keys` (12 floats each, read as
/// [`transform_of`] reads one), interpolated linearly (`interpolation` 0) or decomposed (1),
/// checked as a world checks a motion; refusals name the argument (and the key) at fault.
///
/// # Safety
/// `keys` is NULL or readable for `12 * key_count` floats.
unsafe fn motion_of(
    keys: *const f32,
    key_count: u32,
    interpolation: u32,
) -> Result<Motion, Failure> {
    let bad = |why: String| Failure::new(QvStatus::InvalidArgument, why);
    if key_count as usize > MAX_MOTION_KEYS {
        return Err(bad(format!(
            "key_count: {key_count} is more than {MAX_MOTION_KEYS}"
        )));
    }
    // SAFETY: the caller's contract: `12 * key_count` floats (at most 3,072, no overflow).
    let floats = unsafe { input(keys, 12 * key_count as usize, "keys") }?;
    let keys: Vec<Affine3A> = floats
        .chunks_exact(12)
        .map(|k| affine_of_rows(k.try_into().expect("12 floats")))
        .collect();
    let motion = match interpolation {
        0 => Motion::linear(keys),
        1 => Motion::decomposed(keys),
        other => return Err(bad(format!("interpolation: {other} is neither 0 nor 1"))),
    };
    motion.check(0).map_err(|e| match e {
        WorldError::Motion {
            key: Some(k), why, ..
        } => bad(format!("keys: key {k}: {why}")),
        e => bad(format!(
            "keys: {}",
            e.to_string().trim_start_matches("instance 0: ")
        )),
    })?;
    Ok(motion)
}

/// Starts an empty world builder: `*out` is its handle, else NULL. Free it with
/// `qv_world_builder_free`, or pass it to `qv_world_build`.
///
/// # Safety
/// `out` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn qv_world_builder_new(out: *mut *mut QvWorldBuilder) -> QvStatus {
    guard("qv_world_builder_new", || {
        non_null(out, "out")?;
        let handle = Box::new(QvWorldBuilder {
            builder: WorldBuilder::new(),
            indices: Vec::new(),
        });
        // SAFETY: not NULL (checked) and writable (the caller's contract).
        unsafe { out.write(Box::into_raw(handle)) };
        Ok(())
    })
}

/// Frees a builder not built; NULL is ignored.
///
/// # Safety
/// `builder` is NULL or a live builder handle no other thread uses, not used again.
#[no_mangle]
pub unsafe extern "C" fn qv_world_builder_free(builder: *mut QvWorldBuilder) {
    // SAFETY: the caller's contract.
    unsafe { free_handle("qv_world_builder_free", builder) }
}

/// Adds an indexed triangle mesh as a geometry (buffers as `qv_bvh_build_indexed` reads
/// them, copied now); `*geometry_id` is its id (0, 1, 2, ... in the order added).
///
/// # Safety
/// `builder` a live builder handle or NULL; the buffers NULL or readable for their counts and
/// strides; `geometry_id` NULL or writable.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn qv_world_builder_add_mesh(
    builder: *mut QvWorldBuilder,
    vertices: *const f32,
    vertex_count: usize,
    vertex_stride_bytes: usize,
    indices: *const u32,
    triangle_count: usize,
    index_stride_bytes: usize,
    geometry_id: *mut u32,
) -> QvStatus {
    let mesh = Mesh {
        vertices,
        vertex_count,
        vertex_stride_bytes,
        indices,
        triangle_count,
        index_stride_bytes,
    };
    guard("qv_world_builder_add_mesh", || {
        // SAFETY: the caller's contract for each pointer.
        let (b, id) = unsafe {
            (
                builder_mut(builder)?,
                output(geometry_id, 1, "geometry_id")?,
            )
        };
        // SAFETY: the caller's contract for the buffers, passed on unchanged.
        let (positions, tris) = unsafe { mesh.read() }?;
        if b.geometries() == u32::MAX - 1 {
            return Err(world_failure(WorldError::TooMany));
        }
        // Checked above, so the builder never records a bad mesh (which would fail its build).
        let g = b
            .builder
            .add_mesh(&positions, &tris)
            .map_err(|e| bad_mesh("indices", e))?;
        b.indices.push(Some(tris));
        id[0].write(g.0);
        Ok(())
    })
}

/// The most time steps `qv_world_builder_add_moving_mesh` takes for a mesh of no vertices
/// (whose steps are in no buffer of the caller's to bound them).
const MAX_EMPTY_STEPS: usize = 1 << 16;

/// Adds a deforming indexed triangle mesh as a geometry: `step_count` (at least 2) time
/// steps of the same topology, step `j` at time `j / (step_count - 1)` of the shutter.
/// `vertices` holds `step_count * vertex_count` positions, step `j`'s vertex `i` at position
/// `j * vertex_count + i` (every position `vertex_stride_bytes` after the last, read as
/// `qv_world_builder_add_mesh` reads them); `indices` the `triangle_count` triangles every
/// step shares. Copied now; `*geometry_id` is its id. A ray at time `t` meets the triangles
/// interpolated to `t` (as `WorldBuilder::add_moving_triangles`).
///
/// # Safety
/// `builder` a live builder handle or NULL; the buffers NULL or readable for their counts and
/// strides; `geometry_id` NULL or writable.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn qv_world_builder_add_moving_mesh(
    builder: *mut QvWorldBuilder,
    vertices: *const f32,
    vertex_count: usize,
    vertex_stride_bytes: usize,
    step_count: usize,
    indices: *const u32,
    triangle_count: usize,
    index_stride_bytes: usize,
    geometry_id: *mut u32,
) -> QvStatus {
    guard("qv_world_builder_add_moving_mesh", || {
        // SAFETY: the caller's contract for each pointer.
        let (b, id) = unsafe {
            (
                builder_mut(builder)?,
                output(geometry_id, 1, "geometry_id")?,
            )
        };
        if step_count < 2 {
            return Err(Failure::new(
                QvStatus::InvalidArgument,
                format!("step_count: {step_count} time steps (a moving mesh takes at least 2)"),
            ));
        }
        // Steps of no vertices read no bytes: bounded here, not by the caller's buffer.
        if vertex_count == 0 && step_count > MAX_EMPTY_STEPS {
            return Err(Failure::new(
                QvStatus::InvalidArgument,
                format!(
                    "step_count: {step_count} time steps of no vertices (at most \
                     {MAX_EMPTY_STEPS})"
                ),
            ));
        }
        let total = vertex_count.checked_mul(step_count).ok_or_else(|| {
            Failure::new(
                QvStatus::InvalidArgument,
                format!("vertex_count: {vertex_count} vertices at {step_count} steps overflow"),
            )
        })?;
        // SAFETY: the caller's contract for the buffers, passed on unchanged.
        let positions = unsafe { read_vertices(vertices, total, vertex_stride_bytes) }?;
        // SAFETY: as above.
        let tris =
            unsafe { read_indices(indices, triangle_count, index_stride_bytes, vertex_count) }?;
        if b.geometries() == u32::MAX - 1 {
            return Err(world_failure(WorldError::TooMany));
        }
        let steps: Vec<Vec<Triangle>> = (0..step_count)
            .map(|j| {
                let p = &positions[j * vertex_count..(j + 1) * vertex_count];
                tris.iter()
                    .map(|t| {
                        let v = |k: usize| Vec3A::from(p[t[k] as usize]);
                        Triangle::new(v(0), v(1), v(2))
                    })
                    .collect()
            })
            .collect();
        // Checked above (the steps, their sizes, finite vertices), so the builder never
        // records bad steps (which would fail its build).
        let g = b
            .builder
            .add_moving_triangles(steps)
            .map_err(world_failure)?;
        b.indices.push(None);
        id[0].write(g.0);
        Ok(())
    })
}

/// Places geometry `geometry` by `transform` (object to world, 12 floats, row-major 3×4: row
/// `r` is `transform[4r..4r+4]`, the last column the translation), seen by rays whose mask
/// shares a bit with `mask`; `*instance_id` is its id (0, 1, 2, ... in the order added).
///
/// # Safety
/// `builder` a live builder handle or NULL; `transform` NULL or readable for 12 floats;
/// `instance_id` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn qv_world_builder_add_instance(
    builder: *mut QvWorldBuilder,
    geometry: u32,
    transform: *const f32,
    mask: u32,
    instance_id: *mut u32,
) -> QvStatus {
    guard("qv_world_builder_add_instance", || {
        // SAFETY: the caller's contract for each pointer.
        let (b, m, id) = unsafe {
            (
                builder_mut(builder)?,
                transform_of(transform)?,
                output(instance_id, 1, "instance_id")?,
            )
        };
        if geometry >= b.geometries() {
            return Err(Failure::new(
                QvStatus::InvalidArgument,
                format!(
                    "geometry: {geometry} does not exist (the builder has {})",
                    b.geometries()
                ),
            ));
        }
        let i = b
            .builder
            .add_instance(Instance::of(GeometryId(geometry)).transform(m).mask(mask));
        id[0].write(i.0);
        Ok(())
    })
}

/// Places geometry `geometry` moving over the shutter through `key_count` transforms
/// (`keys`: `12 * key_count` floats, each key read as `qv_world_builder_add_instance` reads
/// its transform), evenly spaced from time 0 to 1, interpolated linearly (`interpolation`
/// 0) or decomposed (1: rotations turn at a constant speed); seen by rays whose mask shares
/// a bit with `mask`; `*instance_id` is its id.
///
/// # Safety
/// `builder` a live builder handle or NULL; `keys` NULL or readable for `12 * key_count`
/// floats; `instance_id` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn qv_world_builder_add_moving_instance(
    builder: *mut QvWorldBuilder,
    geometry: u32,
    keys: *const f32,
    key_count: u32,
    interpolation: u32,
    mask: u32,
    instance_id: *mut u32,
) -> QvStatus {
    guard("qv_world_builder_add_moving_instance", || {
        // SAFETY: the caller's contract for each pointer.
        let (b, motion, id) = unsafe {
            (
                builder_mut(builder)?,
                motion_of(keys, key_count, interpolation)?,
                output(instance_id, 1, "instance_id")?,
            )
        };
        if geometry >= b.geometries() {
            return Err(Failure::new(
                QvStatus::InvalidArgument,
                format!(
                    "geometry: {geometry} does not exist (the builder has {})",
                    b.geometries()
                ),
            ));
        }
        let inst = Instance::of(GeometryId(geometry)).mask(mask);
        let i = b.builder.add_moving_instance(inst, motion);
        id[0].write(i.0);
        Ok(())
    })
}

/// Gives geometry `geometry` a filter: each candidate hit of it, in any instance, is kept
/// only when `filter(user, &candidate)` returns nonzero. Replaces an earlier filter.
///
/// # Safety
/// `builder` a live builder handle or NULL; `filter` NULL or a function that honours
/// `quiver.h`'s contract (callable from any thread, concurrently, with `user`; never
/// unwinding), for as long as the world built from this builder lives.
#[no_mangle]
pub unsafe extern "C" fn qv_world_builder_set_filter(
    builder: *mut QvWorldBuilder,
    geometry: u32,
    filter: QvFilterFn,
    user: *mut c_void,
) -> QvStatus {
    guard("qv_world_builder_set_filter", || {
        // SAFETY: the caller's contract for `builder`.
        let b = unsafe { builder_mut(builder) }?;
        let Some(f) = filter else {
            return Err(Failure::null("filter"));
        };
        let user = SharedUser(user);
        let keep = move |h: &WorldHit| {
            let candidate = QvHit::of_world(Some(*h));
            // SAFETY: the caller promised `f` may be called from any thread, concurrently,
            // with `user`, while the world lives (it is called only by the world's queries);
            // `candidate` is a valid QvHit for the duration of the call.
            unsafe { f(user.get(), &candidate) != 0 }
        };
        b.builder
            .set_filter(GeometryId(geometry), keep)
            .map_err(world_failure)
    })
}

/// Gives geometry `geometry` its own build options (`*options`, read as
/// `qv_bvh_build_indexed_with` reads them), used rather than those `qv_world_build_with` is
/// given. Replaces earlier options.
///
/// # Safety
/// `builder` a live builder handle or NULL; `options` NULL or readable, its `layout` NULL or
/// a NUL-terminated string.
#[no_mangle]
pub unsafe extern "C" fn qv_world_builder_set_options(
    builder: *mut QvWorldBuilder,
    geometry: u32,
    options: *const QvBuildOptions,
) -> QvStatus {
    guard("qv_world_builder_set_options", || {
        // SAFETY: the caller's contract for `builder`.
        let b = unsafe { builder_mut(builder) }?;
        non_null(options, "options")?;
        // SAFETY: not NULL (checked); the caller's contract for what it points to.
        let options = unsafe { options_of(options) }?;
        b.builder
            .set_options(GeometryId(geometry), &options)
            .map_err(world_failure)
    })
}

/// Builds the world (every geometry's BVH and the top level, on rayon's global pool) and
/// consumes the builder, whether or not the build succeeds (except when `builder` or `out` is
/// NULL: then nothing is consumed). `*out` is the world's handle, else NULL.
/// `qv_world_build_with` with the default options.
///
/// # Safety
/// `builder` a live builder handle no other thread uses, or NULL; not used again unless this
/// returns `QV_NULL_POINTER`. `out` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn qv_world_build(
    builder: *mut QvWorldBuilder,
    out: *mut *mut QvWorld,
) -> QvStatus {
    // SAFETY: the caller's contract, which `build` asks; no options.
    unsafe { build("qv_world_build", builder, std::ptr::null(), out) }
}

/// As `qv_world_build`, with `*options` (NULL: the defaults) for the top level and every
/// geometry without options of its own. Refused options consume the builder too.
///
/// # Safety
/// As `qv_world_build`; `options` NULL or readable, its `layout` NULL or a NUL-terminated
/// string.
#[no_mangle]
pub unsafe extern "C" fn qv_world_build_with(
    builder: *mut QvWorldBuilder,
    options: *const QvBuildOptions,
    out: *mut *mut QvWorld,
) -> QvStatus {
    // SAFETY: the caller's contract, which `build` asks.
    unsafe { build("qv_world_build_with", builder, options, out) }
}

/// The body of exported function `name`: the world `builder` builds with `options`, into
/// `*out`; consumes the builder unless `builder` or `out` is NULL.
///
/// # Safety
/// `builder` a live builder handle no other thread uses, or NULL; `options` NULL or a
/// readable `QvBuildOptions` whose `layout` is NULL or NUL-terminated; `out` NULL or
/// writable.
unsafe fn build(
    name: &str,
    builder: *mut QvWorldBuilder,
    options: *const QvBuildOptions,
    out: *mut *mut QvWorld,
) -> QvStatus {
    guard(name, || {
        non_null(out, "out")?;
        non_null(builder, "builder")?;
        // SAFETY: `out` is not NULL (checked) and writable (the caller's contract).
        unsafe { out.write(std::ptr::null_mut()) };
        // SAFETY: a live builder handle is a `Box` from `Box::into_raw`, given back once (the
        // contract: the builder is consumed here) and used by no other thread. Taken before
        // the options are read, so that refused options consume it as a failed build does.
        let b = unsafe { Box::from_raw(builder) };
        // SAFETY: the caller's contract for `options`.
        let options = unsafe { options_of(options) }?;
        let QvWorldBuilder { builder, indices } = *b;
        let world = builder.build(&options).map_err(world_failure)?;
        // SAFETY: as above for `out`.
        unsafe { out.write(Box::into_raw(Box::new(QvWorld { world, indices }))) };
        Ok(())
    })
}

/// Frees a world; NULL is ignored.
///
/// # Safety
/// `world` NULL or a live world handle no other thread uses, not used again.
#[no_mangle]
pub unsafe extern "C" fn qv_world_free(world: *mut QvWorld) {
    // SAFETY: the caller's contract.
    unsafe { free_handle("qv_world_free", world) }
}

/// The point of the world's triangles nearest `point` within `max_distance` (inclusive;
/// `INFINITY` for any distance), measured in world space, into `*hit` (the miss record when
/// none lies that near, or for a non-finite point or a NaN or negative distance); moving
/// instances where they are at time 0.
///
/// # Safety
/// `world` a live world handle or NULL; `point` readable for three floats and `hit`
/// writable, or NULL.
#[no_mangle]
pub unsafe extern "C" fn qv_world_closest_point(
    world: *const QvWorld,
    point: *const f32,
    max_distance: f32,
    hit: *mut QvPointHit,
) -> QvStatus {
    // SAFETY: the caller's contract, which `closest_point` asks.
    unsafe {
        closest_point("qv_world_closest_point", world, point, hit, |w, p| {
            w.closest_point(p, max_distance)
        })
    }
}

/// As `qv_world_closest_point`, with each moving instance where its keys place it at `time`
/// (clamped into [0, 1], NaN as 0, as a ray's time is).
///
/// # Safety
/// As `qv_world_closest_point`.
#[no_mangle]
pub unsafe extern "C" fn qv_world_closest_point_at(
    world: *const QvWorld,
    point: *const f32,
    max_distance: f32,
    time: f32,
    hit: *mut QvPointHit,
) -> QvStatus {
    // SAFETY: the caller's contract, which `closest_point` asks.
    unsafe {
        closest_point("qv_world_closest_point_at", world, point, hit, |w, p| {
            w.closest_point_at(p, max_distance, time)
        })
    }
}

/// The body of exported function `name`: `query`'s answer for the world and the point at
/// `point` into `*hit`.
///
/// # Safety
/// `world` a live world handle or NULL; `point` readable for three floats and `hit`
/// writable, or NULL.
unsafe fn closest_point(
    name: &str,
    world: *const QvWorld,
    point: *const f32,
    hit: *mut QvPointHit,
    query: impl FnOnce(&World, Vec3A) -> Option<WorldPointHit>,
) -> QvStatus {
    guard(name, || {
        non_null(world, "world")?;
        // SAFETY: the caller's contract for each pointer (three floats at `point`, one hit);
        // `world` is not NULL (checked) and live.
        let (w, point, hit) = unsafe {
            (
                &(*world).world,
                input(point, 3, "point")?,
                output(hit, 1, "hit")?,
            )
        };
        let p = Vec3A::new(point[0], point[1], point[2]);
        hit[0].write(QvPointHit::of_world(query(w, p)));
        Ok(())
    })
}

/// Writes the world to the file `path` (created or replaced, all or nothing) in quiver's world file format;
/// filters are not saved.
///
/// # Safety
/// `world` a live world handle or NULL; `path` NULL or a NUL-terminated string.
#[no_mangle]
pub unsafe extern "C" fn qv_world_save(world: *const QvWorld, path: *const c_char) -> QvStatus {
    guard("qv_world_save", || {
        non_null(world, "world")?;
        // SAFETY: the caller's contract for each pointer; `world` is not NULL (checked).
        let (w, path) = unsafe { (&(*world).world, path_of(path)?) };
        files::save(&path, |file| w.save(file))
    })
}

/// Reads a world `qv_world_save` wrote from the file `path`, checked completely before it is
/// returned. On success `*out` is the new handle (free it with `qv_world_free`), else NULL.
///
/// # Safety
/// `path` NULL or a NUL-terminated string; `out` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn qv_world_load(path: *const c_char, out: *mut *mut QvWorld) -> QvStatus {
    guard("qv_world_load", || {
        non_null(out, "out")?;
        // SAFETY: not NULL (checked) and writable (the caller's contract): cleared first, so
        // a refused call leaves no stale handle.
        unsafe { out.write(std::ptr::null_mut()) };
        // SAFETY: the caller's contract for `path`.
        let path = unsafe { path_of(path)? };
        let world = files::load(&path, World::from_bytes)?;
        let handle = QvWorld {
            world,
            indices: Vec::new(),
        };
        // SAFETY: as above for `out`.
        unsafe { out.write(Box::into_raw(Box::new(handle))) };
        Ok(())
    })
}

/// The closest hit of `*ray` into `*hit` (the miss record when nothing is hit).
///
/// # Safety
/// `world` a live world handle or NULL; `ray` readable and `hit` writable, or NULL.
#[no_mangle]
pub unsafe extern "C" fn qv_world_closest_hit(
    world: *const QvWorld,
    ray: *const QvRay,
    hit: *mut QvHit,
) -> QvStatus {
    // SAFETY: the caller's contract, which `trace::closest_hit` asks.
    unsafe { trace::closest_hit("qv_world_closest_hit", world, ray, hit) }
}

/// Whether anything is hit within `*ray`'s interval: `*occluded` is 1 or 0.
///
/// # Safety
/// `world` a live world handle or NULL; `ray` readable and `occluded` writable, or NULL.
#[no_mangle]
pub unsafe extern "C" fn qv_world_any_hit(
    world: *const QvWorld,
    ray: *const QvRay,
    occluded: *mut c_int,
) -> QvStatus {
    // SAFETY: the caller's contract, which `trace::any_hit` asks.
    unsafe { trace::any_hit("qv_world_any_hit", world, ray, occluded) }
}

/// The closest hits of `n` rays into `hits[0..n]`, traced in parallel.
///
/// # Safety
/// `world` a live world handle or NULL; `rays` readable and `hits` writable for `n`
/// elements, not overlapping, or NULL.
#[no_mangle]
pub unsafe extern "C" fn qv_world_closest_hits(
    world: *const QvWorld,
    rays: *const QvRay,
    n: usize,
    hits: *mut QvHit,
) -> QvStatus {
    // SAFETY: the caller's contract, which `trace::closest_hits` asks.
    unsafe { trace::closest_hits("qv_world_closest_hits", world, rays, n, hits) }
}

/// Whether each of `n` rays hits anything: `occluded[i]` is 1 or 0; traced in parallel.
///
/// # Safety
/// `world` a live world handle or NULL; `rays` readable and `occluded` writable for `n`
/// elements, not overlapping, or NULL.
#[no_mangle]
pub unsafe extern "C" fn qv_world_any_hits(
    world: *const QvWorld,
    rays: *const QvRay,
    n: usize,
    occluded: *mut u8,
) -> QvStatus {
    // SAFETY: the caller's contract, which `trace::any_hits` asks.
    unsafe { trace::any_hits("qv_world_any_hits", world, rays, n, occluded) }
}

/// Runs `change` as one edit of `world`, committed (the top level refit or rebuilt) before
/// returning; a refused change changes nothing.
fn edit<T>(
    world: &mut World,
    change: impl FnOnce(&mut WorldEdit<'_>) -> Result<T, WorldError>,
) -> Result<T, Failure> {
    let mut e = world.edit();
    let done = change(&mut e);
    e.commit();
    done.map_err(world_failure)
}

/// Places instance `instance` by `transform` (as `qv_world_builder_add_instance` reads it),
/// as one committed edit.
///
/// # Safety
/// `world` a live world handle no other thread uses during the call, or NULL; `transform`
/// NULL or readable for 12 floats.
#[no_mangle]
pub unsafe extern "C" fn qv_world_set_transform(
    world: *mut QvWorld,
    instance: u32,
    transform: *const f32,
) -> QvStatus {
    guard("qv_world_set_transform", || {
        // SAFETY: the caller's contract for each pointer.
        let (w, m) = unsafe { (world_mut(world)?, transform_of(transform)?) };
        edit(w, |e| e.set_transform(InstanceId(instance), m))
    })
}

/// Moves instance `instance` through `key_count` keys (read as
/// `qv_world_builder_add_moving_instance` reads them) from now on, as one committed edit;
/// `qv_world_set_transform` makes it stand still again.
///
/// # Safety
/// `world` a live world handle no other thread uses during the call, or NULL; `keys` NULL or
/// readable for `12 * key_count` floats.
#[no_mangle]
pub unsafe extern "C" fn qv_world_set_motion(
    world: *mut QvWorld,
    instance: u32,
    keys: *const f32,
    key_count: u32,
    interpolation: u32,
) -> QvStatus {
    guard("qv_world_set_motion", || {
        // SAFETY: the caller's contract for each pointer.
        let (w, motion) = unsafe {
            (
                world_mut(world)?,
                motion_of(keys, key_count, interpolation)?,
            )
        };
        edit(w, |e| e.set_motion(InstanceId(instance), motion))
    })
}

/// Shows instance `instance` only to rays whose mask shares a bit with `mask`, as one
/// committed edit.
///
/// # Safety
/// `world` a live world handle no other thread uses during the call, or NULL.
#[no_mangle]
pub unsafe extern "C" fn qv_world_set_mask(
    world: *mut QvWorld,
    instance: u32,
    mask: u32,
) -> QvStatus {
    guard("qv_world_set_mask", || {
        // SAFETY: the caller's contract for `world`.
        let w = unsafe { world_mut(world) }?;
        edit(w, |e| e.set_mask(InstanceId(instance), mask))
    })
}

/// Removes instance `instance` from the world, as one committed edit; its id is not given
/// again.
///
/// # Safety
/// `world` a live world handle no other thread uses during the call, or NULL.
#[no_mangle]
pub unsafe extern "C" fn qv_world_remove_instance(world: *mut QvWorld, instance: u32) -> QvStatus {
    guard("qv_world_remove_instance", || {
        // SAFETY: the caller's contract for `world`.
        let w = unsafe { world_mut(world) }?;
        edit(w, |e| e.remove_instance(InstanceId(instance)))
    })
}

/// Adds an instance of geometry `geometry` (as `qv_world_builder_add_instance`), as one
/// committed edit (the top level is rebuilt); `*instance_id` is its id, one past every id
/// given before.
///
/// # Safety
/// `world` a live world handle no other thread uses during the call, or NULL; `transform`
/// NULL or readable for 12 floats; `instance_id` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn qv_world_add_instance(
    world: *mut QvWorld,
    geometry: u32,
    transform: *const f32,
    mask: u32,
    instance_id: *mut u32,
) -> QvStatus {
    guard("qv_world_add_instance", || {
        // SAFETY: the caller's contract for each pointer.
        let (w, m, id) = unsafe {
            (
                world_mut(world)?,
                transform_of(transform)?,
                output(instance_id, 1, "instance_id")?,
            )
        };
        let instance = Instance::of(GeometryId(geometry)).transform(m).mask(mask);
        let i = edit(w, |e| e.add_instance(instance))?;
        id[0].write(i.0);
        Ok(())
    })
}

/// The bytes the world holds into `*bytes`: the top level, every geometry's BVH and
/// triangles once (however many instances place it), the instance records and motion keys
/// (the core's `World::footprint().kept`); not the index buffers kept for
/// `qv_world_refit_mesh`, filters, nor the handle itself.
///
/// # Safety
/// `world` a live world handle or NULL; `bytes` writable or NULL.
#[no_mangle]
pub unsafe extern "C" fn qv_world_footprint(world: *const QvWorld, bytes: *mut usize) -> QvStatus {
    guard("qv_world_footprint", || {
        non_null(world, "world")?;
        // SAFETY: the caller's contract for each pointer; `world` is not NULL (checked) and
        // live.
        let (w, bytes) = unsafe { (&(*world).world, output(bytes, 1, "bytes")?) };
        bytes[0].write(w.footprint().kept);
        Ok(())
    })
}

/// Adds an indexed triangle mesh (buffers as `qv_world_builder_add_mesh` reads them) to the
/// built world as a new geometry, its BVH built now with `*options` (NULL: the defaults), as
/// one committed edit; `*geometry_id` is its id, one past the last. Instance it with
/// `qv_world_add_instance`.
///
/// # Safety
/// `world` a live world handle no other thread uses during the call, or NULL; the buffers
/// NULL or readable for their counts and strides; `options` NULL or readable, its `layout`
/// NULL or a NUL-terminated string; `geometry_id` NULL or writable.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn qv_world_add_mesh(
    world: *mut QvWorld,
    vertices: *const f32,
    vertex_count: usize,
    vertex_stride_bytes: usize,
    indices: *const u32,
    triangle_count: usize,
    index_stride_bytes: usize,
    options: *const QvBuildOptions,
    geometry_id: *mut u32,
) -> QvStatus {
    let mesh = Mesh {
        vertices,
        vertex_count,
        vertex_stride_bytes,
        indices,
        triangle_count,
        index_stride_bytes,
    };
    guard("qv_world_add_mesh", || {
        // SAFETY: the caller's contract for each pointer.
        let (w, id, options, (positions, tris)) = unsafe {
            (
                handle_mut(world)?,
                output(geometry_id, 1, "geometry_id")?,
                options_of(options)?,
                mesh.read()?,
            )
        };
        let g = edit(&mut w.world, |e| e.add_mesh(&positions, &tris, &options))?;
        let g_index = g.0 as usize;
        if w.indices.len() < g_index {
            w.indices.resize(g_index, None);
        }
        w.indices.push(Some(tris));
        id[0].write(g.0);
        Ok(())
    })
}

/// Refits mesh geometry `geometry` to new vertex positions for the same triangles (the index
/// buffer it was added with, kept since; vertices read as `qv_world_builder_add_mesh` reads
/// them), as one committed edit: every instance placing it follows.
///
/// # Safety
/// `world` a live world handle no other thread uses during the call, or NULL; `vertices` NULL
/// or readable for `vertex_count` vertices `vertex_stride_bytes` apart.
#[no_mangle]
pub unsafe extern "C" fn qv_world_refit_mesh(
    world: *mut QvWorld,
    geometry: u32,
    vertices: *const f32,
    vertex_count: usize,
    vertex_stride_bytes: usize,
) -> QvStatus {
    guard("qv_world_refit_mesh", || {
        // SAFETY: the caller's contract for `world`.
        let w = unsafe { handle_mut(world) }?;
        let bad = |why: String| Failure::new(QvStatus::InvalidArgument, why);
        let n = w.world.geometries().len();
        let Some(kind) = w.world.geometries().get(geometry as usize) else {
            return Err(bad(format!(
                "geometry: {geometry} does not exist (the world has {n})"
            )));
        };
        if let Geometry::MovingTriangles(_) = kind {
            return Err(bad(format!(
                "geometry: {geometry} is a moving mesh, which qv_world_refit_mesh does not refit"
            )));
        }
        let Some(Some(indices)) = w.indices.get(geometry as usize) else {
            return Err(bad(format!(
                "geometry: {geometry} keeps no index buffer to refit with (its world was \
                 loaded from a file; add meshes with qv_world_builder_add_mesh or \
                 qv_world_add_mesh to refit them)"
            )));
        };
        // SAFETY: the caller's contract for the buffer.
        let positions = unsafe { read_vertices(vertices, vertex_count, vertex_stride_bytes) }?;
        edit(&mut w.world, |e| {
            e.refit_mesh(GeometryId(geometry), &positions, indices)
        })
        .map_err(|f| Failure::new(f.status, format!("vertices: {}", f.message)))
    })
}
