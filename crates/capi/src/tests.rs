//! The C API called as C calls it: raw pointers, status codes, the last error's message.

use crate::error::{guard, last_error, QvStatus};
use crate::*;
use std::ffi::{c_int, c_void};
use std::ptr::{null, null_mut};
use std::sync::atomic::{AtomicUsize, Ordering};

/// A unit square in the z = 0 plane: four vertices, two triangles.
const SQUARE: [[f32; 3]; 4] = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];
const INDICES: [[u32; 3]; 2] = [[0, 1, 2], [0, 2, 3]];
const IDENTITY: [f32; 12] = [1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0.];

/// A ray straight down from height 5 above `(x, y)`.
fn down(x: f32, y: f32) -> QvRay {
    QvRay {
        org: [x, y, 5.0],
        t_min: 0.0,
        dir: [0.0, 0.0, -1.0],
        t_max: f32::INFINITY,
        mask: u32::MAX,
        time: 0.0,
    }
}

/// The BVH over `vertices` (packed) and `indices`, or the status and message of a refusal.
fn build(vertices: &[[f32; 3]], indices: &[[u32; 3]]) -> Result<*mut QvBvh, (QvStatus, String)> {
    let mut out = null_mut();
    // SAFETY: both buffers are packed and as long as the counts say.
    let s = unsafe {
        qv_bvh_build_indexed(
            vertices.as_ptr().cast(),
            vertices.len(),
            12,
            indices.as_ptr().cast(),
            indices.len(),
            12,
            &mut out,
        )
    };
    match s {
        QvStatus::Ok => Ok(out),
        s => {
            assert!(out.is_null());
            Err((s, last_error()))
        }
    }
}

/// The closest hit of `ray` in `bvh`.
fn hit(bvh: *const QvBvh, ray: QvRay) -> QvHit {
    let mut h = QvHit::MISS;
    // SAFETY: a live handle, one ray, one hit.
    assert_eq!(
        unsafe { qv_bvh_closest_hit(bvh, &ray, &mut h) },
        QvStatus::Ok
    );
    h
}

#[test]
fn a_bvh_answers_single_rays_and_arrays_alike() {
    let bvh = build(&SQUARE, &INDICES).unwrap();
    let h = hit(bvh, down(0.25, 0.75));
    assert_eq!(
        (h.prim, h.t, h.geometry, h.instance),
        (1, 5.0, QV_INVALID_ID, QV_INVALID_ID)
    );
    assert_eq!(hit(bvh, down(3.0, 0.5)), QvHit::MISS);
    assert_eq!(last_error(), "", "a call that succeeds leaves no message");

    let rays: Vec<QvRay> = (0..1000)
        .map(|i| down((i % 40) as f32 / 30.0, (i / 40) as f32 / 20.0))
        .collect();
    let mut hits = vec![QvHit::MISS; rays.len()];
    let mut occluded = vec![7u8; rays.len()];
    // SAFETY: arrays as long as `n`, not overlapping.
    unsafe {
        assert_eq!(
            qv_bvh_closest_hits(bvh, rays.as_ptr(), rays.len(), hits.as_mut_ptr()),
            QvStatus::Ok
        );
        assert_eq!(
            qv_bvh_any_hits(bvh, rays.as_ptr(), rays.len(), occluded.as_mut_ptr()),
            QvStatus::Ok
        );
        // No rays: NULL arrays are fine.
        assert_eq!(
            qv_bvh_closest_hits(bvh, null(), 0, null_mut()),
            QvStatus::Ok
        );
    }
    for ((ray, h), o) in rays.iter().zip(&hits).zip(&occluded) {
        assert_eq!(*h, hit(bvh, *ray));
        assert_eq!(*o, u8::from(h.prim != QV_INVALID_ID));
        let mut any: c_int = -1;
        // SAFETY: a live handle, one ray, one answer.
        assert_eq!(unsafe { qv_bvh_any_hit(bvh, ray, &mut any) }, QvStatus::Ok);
        assert_eq!(any, c_int::from(*o));
    }
    assert!(hits.iter().filter(|h| h.prim != QV_INVALID_ID).count() > 300);
    // SAFETY: a live handle, freed once.
    unsafe { qv_bvh_free(bvh) };
}

#[test]
fn null_pointers_are_refused_and_named() {
    let mut out = null_mut();
    // SAFETY: NULL where the test says, real buffers elsewhere.
    unsafe {
        let s = qv_bvh_build_indexed(null(), 4, 12, INDICES.as_ptr().cast(), 2, 12, &mut out);
        assert_eq!(s, QvStatus::NullPointer);
        assert_eq!(last_error(), "qv_bvh_build_indexed: vertices is NULL");
        let s = qv_bvh_build_indexed(SQUARE.as_ptr().cast(), 4, 12, null(), 2, 12, &mut out);
        assert_eq!(
            (s, last_error().contains("indices is NULL")),
            (QvStatus::NullPointer, true)
        );
        let s = qv_bvh_build_indexed(
            SQUARE.as_ptr().cast(),
            4,
            12,
            INDICES.as_ptr().cast(),
            2,
            12,
            null_mut(),
        );
        assert_eq!(
            (s, last_error().contains("out is NULL")),
            (QvStatus::NullPointer, true)
        );
        let mut h = QvHit::MISS;
        assert_eq!(
            qv_bvh_closest_hit(null(), &down(0.5, 0.5), &mut h),
            QvStatus::NullPointer
        );
        assert_eq!(last_error(), "qv_bvh_closest_hit: bvh is NULL");
        assert_eq!(
            qv_world_closest_hits(null(), null(), 0, null_mut()),
            QvStatus::NullPointer
        );
        assert_eq!(
            qv_world_build(null_mut(), null_mut()),
            QvStatus::NullPointer
        );
        assert_eq!(qv_bvh_load(null(), &mut out), QvStatus::NullPointer);
        assert_eq!(last_error(), "qv_bvh_load: path is NULL");
        // Freeing NULL is nothing.
        qv_bvh_free(null_mut());
        qv_world_free(null_mut());
        qv_world_builder_free(null_mut());
    }
    assert!(out.is_null());
    // An empty mesh may come with NULL buffers.
    let mut empty = null_mut();
    // SAFETY: no elements, so nothing is read.
    unsafe {
        assert_eq!(
            qv_bvh_build_indexed(null(), 0, 12, null(), 0, 12, &mut empty),
            QvStatus::Ok
        );
    }
    assert_eq!(hit(empty, down(0.5, 0.5)), QvHit::MISS);
    // SAFETY: a live handle, freed once.
    unsafe { qv_bvh_free(empty) };
}

#[test]
fn bad_meshes_are_refused_naming_what_is_wrong() {
    let e = build(&SQUARE, &[[0, 1, 2], [0, 2, 9]]).unwrap_err();
    assert_eq!(e.0, QvStatus::BadMesh);
    assert_eq!(
        e.1,
        "qv_bvh_build_indexed: indices: triangle 1, index 2: vertex 9 does not exist (the mesh \
         has 4 vertices)"
    );
    let mut nan = SQUARE;
    nan[2][1] = f32::NAN;
    let e = build(&nan, &INDICES).unwrap_err();
    assert_eq!(e.0, QvStatus::BadMesh);
    assert!(
        e.1.contains("vertex 2 has a non-finite coordinate (y = NaN)"),
        "{}",
        e.1
    );

    let mut out = null_mut();
    let (v, i) = (SQUARE.as_ptr().cast(), INDICES.as_ptr().cast());
    // SAFETY: the buffers are valid for what the counts and strides that pass the checks say;
    // the refused ones are never read.
    unsafe {
        assert_eq!(
            qv_bvh_build_indexed(v, 4, 8, i, 2, 12, &mut out),
            QvStatus::BadMesh
        );
        assert!(
            last_error().contains(
                "vertex_stride_bytes: positions at byte offset 0 with a stride of 8 bytes"
            ),
            "{}",
            last_error()
        );
        assert_eq!(
            qv_bvh_build_indexed(v, 4, 12, i, 2, 4, &mut out),
            QvStatus::BadMesh
        );
        assert!(
            last_error().contains("index_stride_bytes: a stride of 4 bytes"),
            "{}",
            last_error()
        );
        // Sizes that overflow are refused before a pointer is formed.
        assert_eq!(
            qv_bvh_build_indexed(v, usize::MAX, 16, i, 2, 12, &mut out),
            QvStatus::InvalidArgument
        );
        assert!(last_error().contains("overflow"), "{}", last_error());
        let mut hits = [QvHit::MISS];
        let s = qv_bvh_closest_hits(
            null(),
            [down(0., 0.)].as_ptr(),
            usize::MAX,
            hits.as_mut_ptr(),
        );
        assert_eq!(s, QvStatus::NullPointer, "the handle is checked first");
    }
    assert!(out.is_null());
}

#[test]
fn strided_vertices_and_indices_read_what_packed_ones_hold() {
    // Interleaved vertices: a normal, then the position, 28 bytes apart (unaligned starts are
    // not needed here: 28 is a multiple of 4); index triples padded to 16 bytes.
    let mut vertices = Vec::new();
    for p in SQUARE {
        vertices.extend_from_slice(&[0.0, 0.0, 1.0]);
        vertices.extend_from_slice(&p);
        vertices.push(-1.0);
    }
    let indices: Vec<u32> = INDICES
        .iter()
        .flat_map(|t| [t[0], t[1], t[2], 99])
        .collect();
    let mut out = null_mut();
    // SAFETY: 4 vertices 28 bytes apart from the position of the first; 2 triples 16 apart.
    let s = unsafe {
        qv_bvh_build_indexed(
            vertices[3..].as_ptr(),
            4,
            28,
            indices.as_ptr(),
            2,
            16,
            &mut out,
        )
    };
    assert_eq!(s, QvStatus::Ok, "{}", last_error());
    let packed = build(&SQUARE, &INDICES).unwrap();
    for (x, y) in [(0.25, 0.75), (0.75, 0.25), (0.5, 0.5), (2.0, 0.0)] {
        assert_eq!(hit(out, down(x, y)), hit(packed, down(x, y)));
    }
    // SAFETY: live handles, freed once.
    unsafe {
        qv_bvh_free(out);
        qv_bvh_free(packed);
    }
}

#[test]
fn refits_and_point_queries() {
    let bvh = build(&SQUARE, &INDICES).unwrap();
    let sunk = SQUARE.map(|[x, y, _]| [x, y, -3.0]);
    // SAFETY: a live handle; 4 packed vertices.
    unsafe {
        assert_eq!(qv_bvh_refit(bvh, sunk.as_ptr().cast(), 4, 12), QvStatus::Ok);
    }
    assert_eq!(hit(bvh, down(0.25, 0.75)).t, 8.0);
    // Too few vertices for the kept indices: refused, the BVH unchanged.
    // SAFETY: as above, 2 vertices.
    unsafe {
        assert_eq!(
            qv_bvh_refit(bvh, SQUARE.as_ptr().cast(), 2, 12),
            QvStatus::BadMesh
        );
    }
    assert!(last_error().contains("does not exist"), "{}", last_error());
    assert_eq!(hit(bvh, down(0.25, 0.75)).t, 8.0);

    let mut p = QvPointHit::of(None);
    // SAFETY: a live handle, three floats, one answer.
    unsafe {
        assert_eq!(
            qv_bvh_closest_point(bvh, [0.25, 0.75, 1.0].as_ptr(), f32::INFINITY, &mut p),
            QvStatus::Ok
        );
    }
    assert_eq!((p.prim, p.point, p.distance), (1, [0.25, 0.75, -3.0], 4.0));
    // SAFETY: as above.
    unsafe {
        assert_eq!(
            qv_bvh_closest_point(bvh, [0.25, 0.75, 1.0].as_ptr(), 3.0, &mut p),
            QvStatus::Ok
        );
    }
    assert_eq!((p.prim, p.distance), (QV_INVALID_ID, f32::INFINITY));
    // SAFETY: a live handle, freed once.
    unsafe { qv_bvh_free(bvh) };
}

#[test]
fn a_saved_bvh_loads_and_answers_the_same() {
    let dir = std::env::temp_dir().join(format!("quiver-capi-save-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("square.qbvh");
    let path = std::ffi::CString::new(file.to_str().unwrap()).unwrap();
    let bvh = build(&SQUARE, &INDICES).unwrap();
    let mut loaded = null_mut();
    // SAFETY: a live handle and a NUL-terminated path.
    unsafe {
        assert_eq!(
            qv_bvh_save(bvh, path.as_ptr()),
            QvStatus::Ok,
            "{}",
            last_error()
        );
        assert_eq!(
            qv_bvh_load(path.as_ptr(), &mut loaded),
            QvStatus::Ok,
            "{}",
            last_error()
        );
    }
    for i in 0..400 {
        let ray = down((i % 20) as f32 / 15.0 - 0.1, (i / 20) as f32 / 15.0 - 0.1);
        assert_eq!(hit(loaded, ray), hit(bvh, ray));
    }
    // A loaded BVH has no index buffer to refit with.
    // SAFETY: a live handle; 4 packed vertices.
    unsafe {
        assert_eq!(
            qv_bvh_refit(loaded, SQUARE.as_ptr().cast(), 4, 12),
            QvStatus::InvalidArgument
        );
    }
    assert!(
        last_error().contains("loaded from a file"),
        "{}",
        last_error()
    );

    // A damaged file, and none.
    let mut bytes = std::fs::read(&file).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    std::fs::write(&file, bytes).unwrap();
    let mut again = null_mut();
    let missing = std::ffi::CString::new(dir.join("none").to_str().unwrap()).unwrap();
    // SAFETY: NUL-terminated paths, a writable out.
    unsafe {
        assert_eq!(qv_bvh_load(path.as_ptr(), &mut again), QvStatus::BadFile);
        assert!(last_error().contains("checksum"), "{}", last_error());
        assert_eq!(qv_bvh_load(missing.as_ptr(), &mut again), QvStatus::Io);
        assert_eq!(qv_bvh_save(bvh, missing.as_ptr().add(0)), QvStatus::Ok);
    }
    assert!(again.is_null());
    // SAFETY: live handles, freed once.
    unsafe {
        qv_bvh_free(bvh);
        qv_bvh_free(loaded);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A world of the square placed twice, side by side: instance 0 at the origin, instance 1
/// moved by (2, 0, 0); `filter` on the geometry with `user`, if given.
fn two_squares(filter: QvFilterFn, user: *mut c_void) -> *mut QvWorld {
    let (mut b, mut g, mut i) = (null_mut(), 0, 0);
    let moved = [1., 0., 0., 2., 0., 1., 0., 0., 0., 0., 1., 0.];
    let mut world = null_mut();
    // SAFETY: live handles, packed buffers, 12-float transforms, writable outs.
    unsafe {
        assert_eq!(qv_world_builder_new(&mut b), QvStatus::Ok);
        let s = qv_world_builder_add_mesh(
            b,
            SQUARE.as_ptr().cast(),
            4,
            12,
            INDICES.as_ptr().cast(),
            2,
            12,
            &mut g,
        );
        assert_eq!((s, g), (QvStatus::Ok, 0));
        assert_eq!(
            qv_world_builder_add_instance(b, g, IDENTITY.as_ptr(), 1, &mut i),
            QvStatus::Ok
        );
        assert_eq!(
            qv_world_builder_add_instance(b, g, moved.as_ptr(), 2, &mut i),
            QvStatus::Ok
        );
        assert_eq!(i, 1);
        if filter.is_some() {
            assert_eq!(
                qv_world_builder_set_filter(b, g, filter, user),
                QvStatus::Ok
            );
        }
        assert_eq!(
            qv_world_build(b, &mut world),
            QvStatus::Ok,
            "{}",
            last_error()
        );
    }
    world
}

/// The closest hit of `ray` in `world`.
fn world_hit(world: *const QvWorld, ray: QvRay) -> QvHit {
    let mut h = QvHit::MISS;
    // SAFETY: a live handle, one ray, one hit.
    assert_eq!(
        unsafe { qv_world_closest_hit(world, &ray, &mut h) },
        QvStatus::Ok
    );
    h
}

/// Keeps only triangle 0's hits, counting its calls in the `AtomicUsize` at `user`.
unsafe extern "C" fn only_triangle_0(user: *mut c_void, candidate: *const QvHit) -> c_int {
    // SAFETY: the test passes a pointer to an `AtomicUsize` that outlives the world, and the
    // candidate is valid during the call.
    let (calls, candidate) = unsafe { (&*(user as *const AtomicUsize), &*candidate) };
    calls.fetch_add(1, Ordering::Relaxed);
    c_int::from(candidate.prim == 0 && candidate.geometry == 0)
}

#[test]
fn a_filter_hides_what_it_rejects() {
    let calls = AtomicUsize::new(0);
    let user = &calls as *const AtomicUsize as *mut c_void;
    let world = two_squares(Some(only_triangle_0), user);
    // Triangle 1's half of both squares is gone, triangle 0's stays.
    assert_eq!(world_hit(world, down(0.25, 0.75)), QvHit::MISS);
    assert_eq!(world_hit(world, down(2.25, 0.75)), QvHit::MISS);
    let h = world_hit(world, down(2.75, 0.25));
    assert_eq!((h.prim, h.geometry, h.instance, h.t), (0, 0, 1, 5.0));
    assert!(calls.load(Ordering::Relaxed) >= 3);
    // The arrays too, on rayon's threads.
    let rays: Vec<QvRay> = (0..500)
        .map(|i| down((i % 50) as f32 / 16.0, (i / 50) as f32 / 9.0))
        .collect();
    let mut hits = vec![QvHit::MISS; rays.len()];
    // SAFETY: a live handle, arrays as long as `n`.
    unsafe {
        assert_eq!(
            qv_world_closest_hits(world, rays.as_ptr(), rays.len(), hits.as_mut_ptr()),
            QvStatus::Ok
        );
    }
    for (ray, h) in rays.iter().zip(&hits) {
        assert_eq!(*h, world_hit(world, *ray));
        assert!(h.prim != 1);
    }
    assert!(hits.iter().any(|h| h.prim == 0));
    let mut occluded = vec![7u8; rays.len()];
    // SAFETY: a live handle, arrays as long as `n`.
    unsafe {
        let s = qv_world_any_hits(world, rays.as_ptr(), rays.len(), occluded.as_mut_ptr());
        assert_eq!(s, QvStatus::Ok);
    }
    for (h, o) in hits.iter().zip(&occluded) {
        assert_eq!(
            *o,
            u8::from(h.prim != QV_INVALID_ID),
            "the filter holds for any hit too"
        );
    }
    let unfiltered = two_squares(None, null_mut());
    assert_eq!(world_hit(unfiltered, down(0.25, 0.75)).prim, 1);
    // SAFETY: live handles, freed once.
    unsafe {
        qv_world_free(world);
        qv_world_free(unfiltered);
    }
}

#[test]
fn world_edits_move_hide_remove_and_add_instances() {
    let world = two_squares(None, null_mut());
    let ray = down(2.5, 0.5);
    assert_eq!(world_hit(world, ray).instance, 1);
    let up = [1., 0., 0., 2., 0., 1., 0., 0., 0., 0., 1., 1.];
    // SAFETY: a live handle used by this thread only; 12-float transforms.
    unsafe {
        assert_eq!(qv_world_set_transform(world, 1, up.as_ptr()), QvStatus::Ok);
        assert_eq!(world_hit(world, ray).t, 4.0);
        assert_eq!(qv_world_set_mask(world, 1, 0), QvStatus::Ok);
        assert_eq!(world_hit(world, ray), QvHit::MISS);
        let mut id = 0;
        assert_eq!(
            qv_world_add_instance(world, 0, up.as_ptr(), u32::MAX, &mut id),
            QvStatus::Ok
        );
        assert_eq!(id, 2);
        assert_eq!(world_hit(world, ray).instance, 2);
        assert_eq!(qv_world_remove_instance(world, 2), QvStatus::Ok);
        assert_eq!(world_hit(world, ray), QvHit::MISS);
        let mut occluded: c_int = 7;
        assert_eq!(
            qv_world_any_hit(world, &down(0.5, 0.5), &mut occluded),
            QvStatus::Ok
        );
        assert_eq!(occluded, 1);

        // Refused edits name the instance and change nothing.
        assert_eq!(
            qv_world_remove_instance(world, 2),
            QvStatus::InvalidArgument
        );
        assert!(
            last_error().contains("instance 2 was removed"),
            "{}",
            last_error()
        );
        assert_eq!(qv_world_set_mask(world, 9, 1), QvStatus::InvalidArgument);
        assert!(
            last_error().contains("instance 9 does not exist"),
            "{}",
            last_error()
        );
        let flat = [1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 0., 0.];
        assert_eq!(
            qv_world_set_transform(world, 0, flat.as_ptr()),
            QvStatus::InvalidArgument
        );
        assert!(last_error().contains("transform"), "{}", last_error());
        assert_eq!(
            qv_world_add_instance(world, 5, IDENTITY.as_ptr(), 1, &mut id),
            QvStatus::InvalidArgument
        );
        assert_eq!(world_hit(world, down(0.5, 0.5)).instance, 0);
        qv_world_free(world);
    }
}

#[test]
fn a_builder_refuses_unknown_geometries_and_bad_transforms_at_once() {
    let mut b = null_mut();
    let mut id = 0;
    // SAFETY: a live builder, 12-float transforms, writable outs.
    unsafe {
        assert_eq!(qv_world_builder_new(&mut b), QvStatus::Ok);
        assert_eq!(
            qv_world_builder_add_instance(b, 0, IDENTITY.as_ptr(), 1, &mut id),
            QvStatus::InvalidArgument
        );
        assert!(
            last_error().contains("geometry: 0 does not exist"),
            "{}",
            last_error()
        );
        let s = qv_world_builder_add_mesh(
            b,
            SQUARE.as_ptr().cast(),
            4,
            12,
            [0u32, 1, 4].as_ptr(),
            1,
            12,
            &mut id,
        );
        assert_eq!(s, QvStatus::BadMesh);
        assert_eq!(
            qv_world_builder_set_filter(b, 0, None, null_mut()),
            QvStatus::NullPointer
        );
        assert_eq!(
            qv_world_builder_set_filter(b, 0, Some(only_triangle_0), null_mut()),
            QvStatus::InvalidArgument
        );
        // The refused mesh added nothing: the world builds, empty.
        let mut world = null_mut();
        assert_eq!(
            qv_world_build(b, &mut world),
            QvStatus::Ok,
            "{}",
            last_error()
        );
        assert_eq!(world_hit(world, down(0.5, 0.5)), QvHit::MISS);
        qv_world_free(world);
    }
}

#[test]
fn a_panic_becomes_qv_panic_with_its_message() {
    let s = guard("qv_test", || panic!("deliberately, in a test"));
    assert_eq!(s, QvStatus::Panic);
    assert_eq!(last_error(), "quiver panicked: deliberately, in a test");
    // The next call clears it.
    assert_eq!(guard("qv_test", || Ok(())), QvStatus::Ok);
    assert_eq!(last_error(), "");
    // A panic on one of rayon's threads comes back to the caller too.
    let s = guard("qv_test", || {
        use quiver_rt::rayon::prelude::*;
        (0..100)
            .into_par_iter()
            .for_each(|i| assert!(i != 57, "ray {i}"));
        Ok(())
    });
    assert_eq!(
        (s, last_error()),
        (QvStatus::Panic, "quiver panicked: ray 57".to_string())
    );
    // And the message pointer C receives reads the same text.
    // SAFETY: qv_last_error returns a NUL-terminated string valid until the next call.
    let c = unsafe { std::ffi::CStr::from_ptr(qv_last_error()) };
    assert_eq!(c.to_str().unwrap(), "quiver panicked: ray 57");
}

#[test]
fn a_saved_world_loads_and_answers_the_same() {
    let dir = std::env::temp_dir().join(format!("quiver-capi-world-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("squares.qwld");
    let path = std::ffi::CString::new(file.to_str().unwrap()).unwrap();
    let world = two_squares(None, null_mut());
    let mut loaded = null_mut();
    // SAFETY: a live handle, a NUL-terminated path, a writable out.
    unsafe {
        assert_eq!(qv_world_set_mask(world, 0, 4), QvStatus::Ok);
        assert_eq!(
            qv_world_save(world, path.as_ptr()),
            QvStatus::Ok,
            "{}",
            last_error()
        );
        assert_eq!(
            qv_world_load(path.as_ptr(), &mut loaded),
            QvStatus::Ok,
            "{}",
            last_error()
        );
    }
    let mut hits = 0;
    for i in 0..400 {
        let mut ray = down((i % 20) as f32 / 6.0 - 0.2, (i / 20) as f32 / 15.0 - 0.1);
        ray.mask = [u32::MAX, 4, 2][i % 3];
        let h = world_hit(world, ray);
        hits += usize::from(h.prim != QV_INVALID_ID);
        assert_eq!(world_hit(loaded, ray), h);
    }
    assert!(hits > 100, "{hits}");
    // All or nothing: no temporary file stays; a save that fails (renamed over a directory)
    // leaves what was there and nothing more; a path naming no file is refused.
    let names = || {
        let mut n: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        n.sort();
        n
    };
    assert_eq!(names(), ["squares.qwld"]);
    let sub = dir.join("sub");
    std::fs::create_dir(&sub).unwrap();
    let sub_path = std::ffi::CString::new(sub.to_str().unwrap()).unwrap();
    let root = std::ffi::CString::new("/").unwrap();
    // SAFETY: a live handle and NUL-terminated paths.
    unsafe {
        assert_eq!(qv_world_save(world, sub_path.as_ptr()), QvStatus::Io);
        assert_eq!(
            qv_world_save(world, root.as_ptr()),
            QvStatus::InvalidArgument
        );
    }
    assert!(sub.is_dir());
    assert_eq!(names(), ["squares.qwld", "sub"]);
    // A damaged file, a BVH file where a world belongs, and NULLs.
    let mut bytes = std::fs::read(&file).unwrap();
    bytes[40] ^= 1;
    std::fs::write(&file, bytes).unwrap();
    let mut again = null_mut();
    // SAFETY: NUL-terminated paths, a writable out; NULLs where the test says.
    unsafe {
        assert_eq!(qv_world_load(path.as_ptr(), &mut again), QvStatus::BadFile);
        assert!(last_error().contains("checksum"), "{}", last_error());
        assert!(again.is_null());
        let bvh = build(&SQUARE, &INDICES).unwrap();
        assert_eq!(qv_bvh_save(bvh, path.as_ptr()), QvStatus::Ok);
        assert_eq!(qv_world_load(path.as_ptr(), &mut again), QvStatus::BadFile);
        assert!(last_error().contains("magic"), "{}", last_error());
        assert_eq!(qv_world_load(null(), &mut again), QvStatus::NullPointer);
        assert_eq!(qv_world_save(null(), path.as_ptr()), QvStatus::NullPointer);
        assert_eq!(last_error(), "qv_world_save: world is NULL");
        qv_bvh_free(bvh);
        qv_world_free(world);
        qv_world_free(loaded);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_world_closest_point_names_its_instance() {
    let world = two_squares(None, null_mut());
    let mut p = QvPointHit::of(None);
    // SAFETY: a live handle, three floats, one answer; NULLs where the test says.
    unsafe {
        let s = qv_world_closest_point(world, [2.75, 0.25, 3.0].as_ptr(), f32::INFINITY, &mut p);
        assert_eq!(s, QvStatus::Ok);
        // Above instance 1 (the square moved to x = 2..3), over its triangle 0.
        assert_eq!(
            (p.instance, p.geometry, p.prim, p.point, p.distance),
            (1, 0, 0, [2.75, 0.25, 0.0], 3.0)
        );
        let s = qv_world_closest_point(world, [2.75, 0.25, 3.0].as_ptr(), 2.0, &mut p);
        assert_eq!(s, QvStatus::Ok);
        assert_eq!(
            (p.instance, p.geometry, p.prim, p.distance),
            (QV_INVALID_ID, QV_INVALID_ID, QV_INVALID_ID, f32::INFINITY)
        );
        let s = qv_world_closest_point(world, null(), 1.0, &mut p);
        assert_eq!(s, QvStatus::NullPointer);
        assert_eq!(last_error(), "qv_world_closest_point: point is NULL");
        qv_world_free(world);
    }
}

#[test]
fn a_moving_instance_is_met_where_its_keys_place_it_at_the_ray_time() {
    let (mut b, mut g, mut i) = (null_mut(), 0, 0);
    // The unit square sliding from x = 0 to x = 4 over the shutter.
    let keys = [IDENTITY, [1., 0., 0., 4., 0., 1., 0., 0., 0., 0., 1., 0.]].concat();
    let mut world = null_mut();
    // SAFETY: live handles, packed buffers, 12 floats a key, writable outs.
    unsafe {
        assert_eq!(qv_world_builder_new(&mut b), QvStatus::Ok);
        let s = qv_world_builder_add_mesh(
            b,
            SQUARE.as_ptr().cast(),
            4,
            12,
            INDICES.as_ptr().cast(),
            2,
            12,
            &mut g,
        );
        assert_eq!(s, QvStatus::Ok);
        for (count, interpolation, want) in [
            (1, 0, "keys: the motion has fewer than two keys"),
            (2, 2, "interpolation: 2 is neither 0 nor 1"),
            (300, 0, "key_count: 300 is more than 256"),
        ] {
            let s = qv_world_builder_add_moving_instance(
                b,
                g,
                keys.as_ptr(),
                count,
                interpolation,
                u32::MAX,
                &mut i,
            );
            assert_eq!(s, QvStatus::InvalidArgument);
            assert!(last_error().contains(want), "{}", last_error());
        }
        let flat = [IDENTITY, [0.0; 12]].concat();
        let s = qv_world_builder_add_moving_instance(b, g, flat.as_ptr(), 2, 0, 1, &mut i);
        assert_eq!(s, QvStatus::InvalidArgument);
        assert!(last_error().contains("keys: key 1: "), "{}", last_error());
        let s = qv_world_builder_add_moving_instance(b, g, keys.as_ptr(), 2, 0, 1, &mut i);
        assert_eq!((s, i), (QvStatus::Ok, 0));
        assert_eq!(
            qv_world_build(b, &mut world),
            QvStatus::Ok,
            "{}",
            last_error()
        );
    }
    // At x = 2.5: met from time 0.375 (the square's right edge gets there) to 0.625.
    let at = |time: f32| {
        world_hit(
            world,
            QvRay {
                time,
                ..down(2.5, 0.5)
            },
        )
    };
    assert_eq!(at(0.0), QvHit::MISS);
    assert_eq!(at(1.0), QvHit::MISS);
    assert_eq!((at(0.5).t, at(0.5).instance), (5.0, 0));
    assert_eq!(at(0.4).t, 5.0);
    assert_eq!(at(0.3), QvHit::MISS);
    // SAFETY: a live world handle, freed once.
    unsafe { qv_world_free(world) };
}

#[test]
fn set_motion_moves_a_built_instance_and_closest_point_at_measures_it_at_a_time() {
    let world = two_squares(None, null_mut());
    // Instance 0 (the unit square at z = 0) rising to z = 4 over the shutter.
    let up4 = [1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 4.];
    let rise = [IDENTITY, up4].concat();
    let p = [0.25, 0.25, 3.0];
    let at = |time: f32| {
        let mut h = QvPointHit::of(None);
        // SAFETY: a live handle, three floats, one answer.
        let s =
            unsafe { qv_world_closest_point_at(world, p.as_ptr(), f32::INFINITY, time, &mut h) };
        assert_eq!(s, QvStatus::Ok, "{}", last_error());
        (h.instance, h.prim, h.point, h.distance)
    };
    let still = at(0.5);
    assert_eq!((still.0, still.3), (0, 3.0), "standing still, at any time");
    // SAFETY: a live handle used by this thread only; key buffers as long as their counts
    // say (NULL where the test says).
    unsafe {
        // Refused motions name what is wrong and change nothing.
        let nan = [IDENTITY, [f32::NAN; 12]].concat();
        for (instance, keys, count, interpolation, status, want) in [
            (
                9,
                rise.as_ptr(),
                2,
                0,
                QvStatus::InvalidArgument,
                "instance 9 does not exist",
            ),
            (
                0,
                null(),
                0,
                0,
                QvStatus::InvalidArgument,
                "keys: the motion has fewer than two keys",
            ),
            (
                0,
                rise.as_ptr(),
                1,
                1,
                QvStatus::InvalidArgument,
                "fewer than two keys",
            ),
            (
                0,
                rise.as_ptr(),
                300,
                0,
                QvStatus::InvalidArgument,
                "key_count: 300 is more than 256",
            ),
            (
                0,
                nan.as_ptr(),
                2,
                0,
                QvStatus::InvalidArgument,
                "keys: key 1: not finite",
            ),
            (
                0,
                rise.as_ptr(),
                2,
                7,
                QvStatus::InvalidArgument,
                "interpolation: 7 is neither 0 nor 1",
            ),
            (0, null(), 2, 0, QvStatus::NullPointer, "keys is NULL"),
        ] {
            let s = qv_world_set_motion(world, instance, keys, count, interpolation);
            assert_eq!(s, status, "{want}: {}", last_error());
            assert!(
                last_error().starts_with("qv_world_set_motion: "),
                "{}",
                last_error()
            );
            assert!(last_error().contains(want), "{}", last_error());
            assert_eq!(at(0.5), still, "a refused motion changes nothing");
        }
        assert_eq!(
            qv_world_set_motion(null_mut(), 0, rise.as_ptr(), 2, 0),
            QvStatus::NullPointer
        );
        assert_eq!(
            qv_world_set_motion(world, 0, rise.as_ptr(), 2, 0),
            QvStatus::Ok
        );
    }
    // Measured where the keys place the square: z = 0 at time 0 (and NaN, and before the
    // shutter), z = 2 half way, z = 4 at its end and after.
    for (time, z, distance) in [
        (0.0, 0.0, 3.0),
        (f32::NAN, 0.0, 3.0),
        (-1.0, 0.0, 3.0),
        (0.5, 2.0, 1.0),
        (1.0, 4.0, 1.0),
        (9.0, 4.0, 1.0),
    ] {
        let (instance, _, point, d) = at(time);
        assert_eq!(
            (instance, point, d),
            (0, [0.25, 0.25, z], distance),
            "time {time}"
        );
    }
    let mut h = QvPointHit::of(None);
    // SAFETY: a live handle, three floats, one answer; NULLs where the test says.
    unsafe {
        let s = qv_world_closest_point(world, p.as_ptr(), f32::INFINITY, &mut h);
        assert_eq!(s, QvStatus::Ok);
        assert_eq!((h.instance, h.prim, h.point, h.distance), at(0.0));
        // A ray at half time meets it at z = 2.
        let ray = QvRay {
            time: 0.5,
            ..down(0.25, 0.25)
        };
        assert_eq!(world_hit(world, ray).t, 3.0);
        // Decomposed keys too: instance 1 (x = 2..3) sliding 4 along y.
        let slide = [
            [1., 0., 0., 2., 0., 1., 0., 0., 0., 0., 1., 0.],
            [1., 0., 0., 2., 0., 1., 0., 4., 0., 0., 1., 0.],
        ]
        .concat();
        assert_eq!(
            qv_world_set_motion(world, 1, slide.as_ptr(), 2, 1),
            QvStatus::Ok
        );
        let q = [2.5, 2.5, 1.0];
        let s = qv_world_closest_point_at(world, q.as_ptr(), f32::INFINITY, 0.5, &mut h);
        assert_eq!(s, QvStatus::Ok);
        assert_eq!((h.instance, h.point, h.distance), (1, [2.5, 2.5, 0.0], 1.0));
        let s = qv_world_closest_point_at(world, null(), 1.0, 0.5, &mut h);
        assert_eq!(s, QvStatus::NullPointer);
        assert_eq!(last_error(), "qv_world_closest_point_at: point is NULL");
        // Set still again by a transform.
        assert_eq!(
            qv_world_set_transform(world, 0, IDENTITY.as_ptr()),
            QvStatus::Ok
        );
        assert_eq!(at(0.5), still);
        qv_world_free(world);
    }
}

/// The square at three steps (z = 0, sunk to z = -2 and moved along x, back up to z = -1),
/// each vertex 16 bytes after the last: step `j`'s vertex `i` at `4 * j + i`.
fn moving_square() -> Vec<[f32; 4]> {
    let mut out = Vec::new();
    for (dx, z) in [(0.0, 0.0), (0.5, -2.0), (0.25, -1.0)] {
        for v in SQUARE {
            out.push([v[0] + dx, v[1], z, f32::NAN]);
        }
    }
    out
}

/// Adds `vertices` (16-byte stride, `vertex_count` a step) at `steps` steps over `INDICES`.
///
/// # Safety
/// `builder` a live builder handle or NULL.
unsafe fn add_moving(
    builder: *mut QvWorldBuilder,
    vertices: &[[f32; 4]],
    vertex_count: usize,
    steps: usize,
    indices: &[[u32; 3]],
) -> Result<u32, (QvStatus, String)> {
    assert!(vertices.len() >= vertex_count * steps);
    let mut g = u32::MAX;
    // SAFETY: the buffers are as long as the counts say (asserted); the caller's builder.
    let s = unsafe {
        qv_world_builder_add_moving_mesh(
            builder,
            vertices.as_ptr().cast(),
            vertex_count,
            16,
            steps,
            indices.as_ptr().cast(),
            indices.len(),
            12,
            &mut g,
        )
    };
    match s {
        QvStatus::Ok => Ok(g),
        s => Err((s, last_error())),
    }
}

#[test]
fn a_moving_mesh_answers_as_the_rust_apis() {
    use quiver_rt::glam::{Affine3A, Vec3, Vec3A};
    use quiver_rt::{BuildOptions, Instance, RayQuery, Triangle, World};
    let verts = moving_square();
    let moved = [1., 0., 0., 2., 0., 1., 0., 0., 0., 0., 1., 0.];
    let keys = [IDENTITY, moved].concat();
    let (mut b, mut i, mut world) = (null_mut(), 0, null_mut());
    // SAFETY: live handles, buffers as long as their counts, writable outs.
    unsafe {
        assert_eq!(qv_world_builder_new(&mut b), QvStatus::Ok);
        assert_eq!(add_moving(b, &verts, 4, 3, &INDICES), Ok(0));
        assert_eq!(
            qv_world_builder_add_instance(b, 0, IDENTITY.as_ptr(), 1, &mut i),
            QvStatus::Ok
        );
        assert_eq!(
            qv_world_builder_add_moving_instance(b, 0, keys.as_ptr(), 2, 0, 2, &mut i),
            QvStatus::Ok
        );
        assert_eq!(i, 1);
        assert_eq!(
            qv_world_build(b, &mut world),
            QvStatus::Ok,
            "{}",
            last_error()
        );
    }
    // The same world from Rust.
    let steps: Vec<Vec<Triangle>> = (0..3)
        .map(|j| {
            INDICES
                .iter()
                .map(|t| {
                    let v = |k: usize| {
                        let p = verts[4 * j + t[k] as usize];
                        Vec3A::new(p[0], p[1], p[2])
                    };
                    Triangle::new(v(0), v(1), v(2))
                })
                .collect()
        })
        .collect();
    let mut rb = World::builder();
    let g = rb.add_moving_triangles(steps).unwrap();
    rb.add_instance(Instance::of(g).mask(1));
    rb.add_moving_instance(
        Instance::of(g).mask(2),
        quiver_rt::Motion::linear(vec![
            Affine3A::IDENTITY,
            Affine3A::from_translation(Vec3::new(2.0, 0.0, 0.0)),
        ]),
    );
    let want = rb.build(&BuildOptions::default()).unwrap();
    let mut hits = 0;
    for k in 0..400 {
        let (x, y) = ((k % 20) as f32 * 0.19 - 0.3, (k / 20) as f32 * 0.06 - 0.1);
        for time in [0.0, 0.1, 0.3, 0.5, 0.77, 1.0, 1.5, f32::NAN] {
            let ray = QvRay { time, ..down(x, y) };
            let got = world_hit(world, ray);
            let w = want.closest_hit(&ray.to_ray());
            hits += usize::from(w.is_some());
            assert_eq!(
                (got.t.to_bits(), got.prim, got.geometry, got.instance),
                w.map_or(
                    (
                        QvHit::MISS.t.to_bits(),
                        QvHit::MISS.prim,
                        QV_INVALID_ID,
                        QV_INVALID_ID
                    ),
                    |h| (h.t.to_bits(), h.prim, h.geometry.0, h.instance.0)
                ),
                "({x}, {y}) at {time}"
            );
        }
    }
    assert!(hits > 400, "{hits} hits");
    // Saved (world file version 2) and loaded: the same answers, bit for bit.
    let dir = std::env::temp_dir().join(format!("quiver-capi-moving-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = std::ffi::CString::new(dir.join("moving.qwld").to_str().unwrap()).unwrap();
    let mut loaded = null_mut();
    // SAFETY: a live handle, a NUL-terminated path, a writable out.
    unsafe {
        assert_eq!(
            qv_world_save(world, path.as_ptr()),
            QvStatus::Ok,
            "{}",
            last_error()
        );
        assert_eq!(
            qv_world_load(path.as_ptr(), &mut loaded),
            QvStatus::Ok,
            "{}",
            last_error()
        );
    }
    for k in 0..400 {
        let (x, y) = ((k % 20) as f32 * 0.19 - 0.3, (k / 20) as f32 * 0.06 - 0.1);
        for time in [0.0, 0.3, 0.5, 0.9, 1.0] {
            let ray = QvRay { time, ..down(x, y) };
            let (a, b) = (world_hit(world, ray), world_hit(loaded, ray));
            assert_eq!(
                (a.t.to_bits(), a.prim, a.instance),
                (b.t.to_bits(), b.prim, b.instance)
            );
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
    // SAFETY: live handles, not used again.
    unsafe {
        qv_world_free(world);
        qv_world_free(loaded);
    }
}

#[test]
fn bad_moving_meshes_are_refused_adding_nothing() {
    let verts = moving_square();
    let mut nan = verts.clone();
    nan[9][1] = f32::NAN; // step 2, vertex 1
    let mut b = null_mut();
    let mut g = 0;
    // SAFETY: live handles, buffers as long as their counts (or NULL), writable outs.
    unsafe {
        assert_eq!(qv_world_builder_new(&mut b), QvStatus::Ok);
        let refused = |r: Result<u32, (QvStatus, String)>, status: QvStatus, words: &str| {
            let (s, e) = r.unwrap_err();
            assert_eq!(s, status, "{e}");
            assert!(e.contains(words), "{e}");
            assert!(e.starts_with("qv_world_builder_add_moving_mesh"), "{e}");
        };
        refused(
            add_moving(null_mut(), &verts, 4, 3, &INDICES),
            QvStatus::NullPointer,
            "builder",
        );
        for steps in [0, 1] {
            refused(
                add_moving(b, &verts, 4, steps, &INDICES),
                QvStatus::InvalidArgument,
                "step_count",
            );
        }
        refused(
            add_moving(b, &[], 0, 1 << 20, &[]),
            QvStatus::InvalidArgument,
            "step_count",
        );
        refused(
            add_moving(b, &nan, 4, 3, &INDICES),
            QvStatus::BadMesh,
            "vertex 9 has a non-finite",
        );
        // Index 4 is step 1's vertex 0, not this step's: out of range.
        refused(
            add_moving(b, &verts, 4, 3, &[[0, 1, 4]]),
            QvStatus::BadMesh,
            "vertex 4",
        );
        let s = qv_world_builder_add_moving_mesh(
            b,
            null(),
            4,
            16,
            3,
            INDICES.as_ptr().cast(),
            2,
            12,
            &mut g,
        );
        assert_eq!(s, QvStatus::NullPointer);
        let s = qv_world_builder_add_moving_mesh(
            b,
            verts.as_ptr().cast(),
            4,
            16,
            3,
            null(),
            2,
            12,
            &mut g,
        );
        assert_eq!(s, QvStatus::NullPointer);
        let s = qv_world_builder_add_moving_mesh(
            b,
            verts.as_ptr().cast(),
            4,
            16,
            3,
            INDICES.as_ptr().cast(),
            2,
            12,
            null_mut(),
        );
        assert_eq!(s, QvStatus::NullPointer);
        let s = qv_world_builder_add_moving_mesh(
            b,
            verts.as_ptr().cast(),
            usize::MAX / 2,
            16,
            3,
            INDICES.as_ptr().cast(),
            2,
            12,
            &mut g,
        );
        assert_eq!(s, QvStatus::InvalidArgument, "{}", last_error());
        // Nothing was added: the first good mesh is geometry 0, an empty one geometry 1.
        assert_eq!(add_moving(b, &verts, 4, 3, &INDICES), Ok(0));
        assert_eq!(add_moving(b, &[], 0, 5, &[]), Ok(1));
        let mut world = null_mut();
        assert_eq!(
            qv_world_build(b, &mut world),
            QvStatus::Ok,
            "{}",
            last_error()
        );
        qv_world_free(world);
    }
}

/// An `n` by `n` grid of unit squares in the z = 0 plane over `[0, n]²`: square `(x, y)` is
/// triangles `2 * (y * n + x)` (below its diagonal) and the next (above it).
fn grid(n: u32) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let vertices = (0..=n)
        .flat_map(|y| (0..=n).map(move |x| [x as f32, y as f32, 0.0]))
        .collect();
    let at = |x: u32, y: u32| y * (n + 1) + x;
    let indices = (0..n)
        .flat_map(|y| (0..n).map(move |x| (x, y)))
        .flat_map(|(x, y)| {
            let (a, b, c, d) = (at(x, y), at(x + 1, y), at(x + 1, y + 1), at(x, y + 1));
            [[a, b, c], [a, c, d]]
        })
        .collect();
    (vertices, indices)
}

/// Build options of `quality` and the layout named `layout` (a NUL-terminated name), if any.
fn options(quality: u32, layout: Option<&std::ffi::CStr>) -> QvBuildOptions {
    QvBuildOptions {
        quality,
        layout: layout.map_or(null(), |l| l.as_ptr()),
    }
}

/// As [`build`], with `options` (NULL for the defaults).
fn build_with(
    vertices: &[[f32; 3]],
    indices: &[[u32; 3]],
    options: *const QvBuildOptions,
) -> Result<*mut QvBvh, (QvStatus, String)> {
    let mut out = null_mut();
    // SAFETY: both buffers are packed and as long as the counts say; `options` is NULL or
    // the caller's live options.
    let s = unsafe {
        qv_bvh_build_indexed_with(
            vertices.as_ptr().cast(),
            vertices.len(),
            12,
            indices.as_ptr().cast(),
            indices.len(),
            12,
            options,
            &mut out,
        )
    };
    match s {
        QvStatus::Ok => Ok(out),
        s => {
            assert!(out.is_null());
            Err((s, last_error()))
        }
    }
}

/// The footprint of `bvh`.
fn bvh_bytes(bvh: *const QvBvh) -> usize {
    let mut bytes = 0;
    // SAFETY: a live handle, one writable size.
    assert_eq!(unsafe { qv_bvh_footprint(bvh, &mut bytes) }, QvStatus::Ok);
    bytes
}

/// The footprint of `world`.
fn world_bytes(world: *const QvWorld) -> usize {
    let mut bytes = 0;
    // SAFETY: a live handle, one writable size.
    assert_eq!(
        unsafe { qv_world_footprint(world, &mut bytes) },
        QvStatus::Ok
    );
    bytes
}

/// Rays straight down over `[-0.2, 7.6] × [-0.2, 1.3]`, some on the squares' edges and
/// diagonals.
fn rays_over_two_squares() -> Vec<QvRay> {
    (0..40 * 16)
        .map(|i| down((i % 40) as f32 / 5.0 - 0.2, (i / 40) as f32 / 10.0 - 0.2))
        .collect()
}

#[test]
fn build_options_choose_the_preset_and_layout_and_the_hits_stay() {
    let (verts, tris) = grid(6);
    let default = build(&verts, &tris).unwrap();
    let rays: Vec<QvRay> = (0..400)
        .map(|i| down((i % 20) as f32 * 0.33 - 0.1, (i / 20) as f32 * 0.33 - 0.1))
        .collect();
    let layouts = [
        None,
        Some(c"bvh4-quant"),
        Some(c"bvh2-dfs"),
        Some(c"bvh8-dfs"),
    ];
    for quality in [QvQuality::Default, QvQuality::Fast, QvQuality::High] {
        for layout in layouts {
            let o = options(quality as u32, layout);
            let square = build_with(&SQUARE, &INDICES, &o).unwrap();
            let h = hit(square, down(0.25, 0.75));
            assert_eq!((h.t, h.prim), (5.0, 1), "{quality:?} {layout:?}");
            assert_eq!(hit(square, down(0.75, 0.25)).prim, 0);
            assert_eq!(hit(square, down(1.5, 0.5)), QvHit::MISS);
            let bvh = build_with(&verts, &tris, &o).unwrap();
            for &ray in &rays {
                assert_eq!(hit(bvh, ray), hit(default, ray), "{quality:?} {layout:?}");
            }
            // SAFETY: live handles, freed once.
            unsafe {
                qv_bvh_free(square);
                qv_bvh_free(bvh);
            }
        }
    }
    // NULL options are the defaults, as qv_bvh_build_indexed builds.
    let null_options = build_with(&verts, &tris, null()).unwrap();
    assert_eq!(bvh_bytes(null_options), bvh_bytes(default));
    // A moved square refit through a BVH built with options: 2 higher, t = 3.
    let quant = build_with(&SQUARE, &INDICES, &options(1, Some(c"bvh4-quant"))).unwrap();
    let up = SQUARE.map(|[x, y, _]| [x, y, 2.0]);
    // SAFETY: a live handle; 4 packed vertices.
    unsafe {
        assert_eq!(qv_bvh_refit(quant, up.as_ptr().cast(), 4, 12), QvStatus::Ok);
    }
    assert_eq!(
        (
            hit(quant, down(0.25, 0.75)).t,
            hit(quant, down(0.25, 0.75)).prim
        ),
        (3.0, 1)
    );
    // SAFETY: live handles, freed once.
    unsafe {
        qv_bvh_free(quant);
        qv_bvh_free(null_options);
        qv_bvh_free(default);
    }
}

#[test]
fn bad_build_options_are_refused_naming_the_field() {
    let (s, msg) = build_with(&SQUARE, &INDICES, &options(0, Some(c"bvh3"))).unwrap_err();
    assert_eq!(s, QvStatus::InvalidArgument);
    assert!(
        msg.starts_with("qv_bvh_build_indexed_with: options.layout: unknown layout 'bvh3'"),
        "{msg}"
    );
    for name in ["bvh8-dfs", "bvh4-quant", "bvh2-dfs", "bvh2-compact-page"] {
        assert!(msg.contains(name), "{msg}");
    }
    // "bvh8" is not a name: the names are exactly Layout::name's.
    let (s, msg) = build_with(&SQUARE, &INDICES, &options(0, Some(c"bvh8"))).unwrap_err();
    assert_eq!(s, QvStatus::InvalidArgument, "{msg}");
    let (s, msg) = build_with(&SQUARE, &INDICES, &options(7, None)).unwrap_err();
    assert_eq!(s, QvStatus::InvalidArgument);
    assert_eq!(
        msg,
        "qv_bvh_build_indexed_with: options.quality: 7 is not a QvQuality (0 default, 1 fast, \
         2 high)"
    );
    let (s, _) = build_with(&SQUARE, &INDICES, &options(u32::MAX, None)).unwrap_err();
    assert_eq!(s, QvStatus::InvalidArgument);
    let not_utf8 = c"bvh\xff";
    let (s, msg) = build_with(&SQUARE, &INDICES, &options(0, Some(not_utf8))).unwrap_err();
    assert_eq!(s, QvStatus::InvalidArgument);
    assert!(msg.ends_with("options.layout: not UTF-8"), "{msg}");
    // The options are checked as any argument is; a bad mesh is still a bad mesh.
    let (s, _) = build_with(&SQUARE, &[[0, 1, 9]], &options(1, None)).unwrap_err();
    assert_eq!(s, QvStatus::BadMesh);
    // NULL out: refused, nothing read.
    // SAFETY: packed buffers; a NULL out, which is refused.
    let s = unsafe {
        qv_bvh_build_indexed_with(
            SQUARE.as_ptr().cast(),
            4,
            12,
            INDICES.as_ptr().cast(),
            2,
            12,
            null(),
            null_mut(),
        )
    };
    assert_eq!(s, QvStatus::NullPointer);
    assert_eq!(last_error(), "qv_bvh_build_indexed_with: out is NULL");
}

#[test]
fn footprints_are_the_rust_structures_totals() {
    use quiver_rt::{BuildOptions, Bvh, Instance, Layout, World};
    let (verts, tris) = grid(12);
    let square = build(&SQUARE, &INDICES).unwrap();
    let big = build(&verts, &tris).unwrap();
    assert!(bvh_bytes(square) > 0);
    assert!(bvh_bytes(big) > bvh_bytes(square));
    let rust = |v: &[[f32; 3]], t: &[[u32; 3]], o: &BuildOptions<'_>| {
        Bvh::build_mesh(v, t, o).unwrap().footprint().kept
    };
    assert_eq!(
        bvh_bytes(square),
        rust(&SQUARE, &INDICES, &BuildOptions::default())
    );
    assert_eq!(
        bvh_bytes(big),
        rust(&verts, &tris, &BuildOptions::default())
    );
    let quant = build_with(&verts, &tris, &options(1, Some(c"bvh4-quant"))).unwrap();
    let fast_quant = BuildOptions::fast().layout(Layout::Bvh4Quant);
    assert_eq!(bvh_bytes(quant), rust(&verts, &tris, &fast_quant));
    assert_ne!(bvh_bytes(quant), bvh_bytes(big));

    // The world of two squares, and the same built in Rust.
    let world = two_squares(None, null_mut());
    let mut b = World::builder();
    let g = b.add_mesh(&SQUARE, &INDICES).unwrap();
    b.add_instance(Instance::of(g));
    b.add_instance(
        Instance::of(g).transform(quiver_rt::glam::Affine3A::from_translation(
            [2.0, 0.0, 0.0].into(),
        )),
    );
    let rust_world = b.build(&BuildOptions::default()).unwrap();
    assert_eq!(world_bytes(world), rust_world.footprint().kept);
    assert!(world_bytes(world) > bvh_bytes(square));

    let mut bytes = 7;
    // SAFETY: live handles; NULLs where refused.
    unsafe {
        assert_eq!(qv_bvh_footprint(null(), &mut bytes), QvStatus::NullPointer);
        assert_eq!(last_error(), "qv_bvh_footprint: bvh is NULL");
        assert_eq!(qv_bvh_footprint(square, null_mut()), QvStatus::NullPointer);
        assert_eq!(last_error(), "qv_bvh_footprint: bytes is NULL");
        assert_eq!(
            qv_world_footprint(null(), &mut bytes),
            QvStatus::NullPointer
        );
        assert_eq!(qv_world_footprint(world, null_mut()), QvStatus::NullPointer);
        assert_eq!(last_error(), "qv_world_footprint: bytes is NULL");
        assert_eq!(bytes, 7);
        qv_bvh_free(square);
        qv_bvh_free(big);
        qv_bvh_free(quant);
        qv_world_free(world);
    }
}

/// A builder holding the square (geometry 0) placed as [`two_squares`] places it: instance
/// 0 at the origin (mask 1), instance 1 moved by (2, 0, 0) (mask 2).
fn two_squares_builder() -> *mut QvWorldBuilder {
    let (mut b, mut g, mut i) = (null_mut(), 0, 0);
    let moved = [1., 0., 0., 2., 0., 1., 0., 0., 0., 0., 1., 0.];
    // SAFETY: a live handle, packed buffers, 12-float transforms, writable outs.
    unsafe {
        assert_eq!(qv_world_builder_new(&mut b), QvStatus::Ok);
        let s = qv_world_builder_add_mesh(
            b,
            SQUARE.as_ptr().cast(),
            4,
            12,
            INDICES.as_ptr().cast(),
            2,
            12,
            &mut g,
        );
        assert_eq!((s, g), (QvStatus::Ok, 0));
        assert_eq!(
            qv_world_builder_add_instance(b, g, IDENTITY.as_ptr(), 1, &mut i),
            QvStatus::Ok
        );
        assert_eq!(
            qv_world_builder_add_instance(b, g, moved.as_ptr(), 2, &mut i),
            QvStatus::Ok
        );
    }
    b
}

#[test]
fn a_world_built_with_options_answers_as_the_default() {
    let default = two_squares(None, null_mut());
    let rays = rays_over_two_squares();
    let quant = options(QvQuality::Fast as u32, Some(c"bvh4-quant"));
    let binary = options(QvQuality::High as u32, Some(c"bvh2-dfs"));
    for own in [None, Some(&binary)] {
        let b = two_squares_builder();
        let mut world = null_mut();
        // SAFETY: a live builder, consumed by the build; live options; a writable out.
        unsafe {
            if let Some(own) = own {
                assert_eq!(qv_world_builder_set_options(b, 0, own), QvStatus::Ok);
            }
            assert_eq!(qv_world_build_with(b, &quant, &mut world), QvStatus::Ok);
        }
        let h = world_hit(world, down(2.25, 0.75));
        assert_eq!((h.t, h.prim, h.geometry, h.instance), (5.0, 1, 0, 1));
        for &ray in &rays {
            assert_eq!(world_hit(world, ray), world_hit(default, ray), "{ray:?}");
        }
        // SAFETY: a live handle, freed once.
        unsafe { qv_world_free(world) };
    }
    // A world built with NULL options is the default one.
    let b = two_squares_builder();
    let mut world = null_mut();
    // SAFETY: a live builder, consumed; a writable out.
    unsafe {
        assert_eq!(qv_world_build_with(b, null(), &mut world), QvStatus::Ok);
    }
    assert_eq!(world_bytes(world), world_bytes(default));
    // SAFETY: live handles, freed once.
    unsafe {
        qv_world_free(world);
        qv_world_free(default);
    }
}

#[test]
fn bad_world_build_options_are_refused() {
    let b = two_squares_builder();
    let bad_layout = options(0, Some(c"bvh9"));
    // SAFETY: a live builder; options and NULLs as the test says.
    unsafe {
        assert_eq!(
            qv_world_builder_set_options(b, 0, null()),
            QvStatus::NullPointer
        );
        assert_eq!(
            last_error(),
            "qv_world_builder_set_options: options is NULL"
        );
        assert_eq!(
            qv_world_builder_set_options(null_mut(), 0, &options(0, None)),
            QvStatus::NullPointer
        );
        assert_eq!(
            qv_world_builder_set_options(b, 3, &options(0, None)),
            QvStatus::InvalidArgument
        );
        assert!(last_error().contains("geometry 3"), "{}", last_error());
        assert_eq!(
            qv_world_builder_set_options(b, 0, &bad_layout),
            QvStatus::InvalidArgument
        );
        assert!(
            last_error().starts_with("qv_world_builder_set_options: options.layout"),
            "{}",
            last_error()
        );
        // NULL out: nothing consumed, so the builder is still ours to build.
        assert_eq!(
            qv_world_build_with(b, &options(9, None), null_mut()),
            QvStatus::NullPointer
        );
        // Refused options: refused, and the builder consumed (as a failed build consumes it).
        let mut world = std::ptr::dangling_mut::<QvWorld>();
        assert_eq!(
            qv_world_build_with(b, &options(9, None), &mut world),
            QvStatus::InvalidArgument
        );
        assert!(world.is_null());
        assert_eq!(
            last_error(),
            "qv_world_build_with: options.quality: 9 is not a QvQuality (0 default, 1 fast, 2 high)"
        );
        let b = two_squares_builder();
        assert_eq!(
            qv_world_build_with(b, &bad_layout, &mut world),
            QvStatus::InvalidArgument
        );
        assert!(
            last_error().starts_with("qv_world_build_with: options.layout: unknown layout 'bvh9'"),
            "{}",
            last_error()
        );
        assert!(world.is_null());
    }
}

/// Adds the square, moved by `lift` along z, to `world` as a new geometry built with
/// `options` (NULL: the defaults).
fn add_square(
    world: *mut QvWorld,
    lift: f32,
    options: *const QvBuildOptions,
) -> Result<u32, (QvStatus, String)> {
    let verts = SQUARE.map(|[x, y, z]| [x, y, z + lift]);
    let mut g = QV_INVALID_ID;
    // SAFETY: packed buffers as long as their counts; the caller's handle and options.
    let s = unsafe {
        qv_world_add_mesh(
            world,
            verts.as_ptr().cast(),
            4,
            12,
            INDICES.as_ptr().cast(),
            2,
            12,
            options,
            &mut g,
        )
    };
    match s {
        QvStatus::Ok => Ok(g),
        s => Err((s, last_error())),
    }
}

/// Refits geometry `geometry` of `world` to the square moved by `lift` along z.
fn refit_square(world: *mut QvWorld, geometry: u32, lift: f32) -> (QvStatus, String) {
    let verts = SQUARE.map(|[x, y, z]| [x, y, z + lift]);
    // SAFETY: 4 packed vertices; the caller's handle.
    let s = unsafe { qv_world_refit_mesh(world, geometry, verts.as_ptr().cast(), 4, 12) };
    (s, last_error())
}

#[test]
fn add_mesh_and_refit_mesh_edit_a_built_world() {
    let world = two_squares(None, null_mut());
    let far = down(5.75, 0.25);
    assert_eq!(world_hit(world, far), QvHit::MISS);
    let bytes = world_bytes(world);
    let g = add_square(world, 0.0, &options(1, Some(c"bvh4-quant"))).unwrap();
    assert_eq!(g, 1);
    assert!(world_bytes(world) > bytes);
    // Added, not yet placed.
    assert_eq!(world_hit(world, far), QvHit::MISS);
    let at5 = [1., 0., 0., 5., 0., 1., 0., 0., 0., 0., 1., 0.];
    let mut i = 0;
    // SAFETY: a live handle, a 12-float transform, a writable id.
    unsafe {
        assert_eq!(
            qv_world_add_instance(world, g, at5.as_ptr(), u32::MAX, &mut i),
            QvStatus::Ok
        );
    }
    assert_eq!(i, 2);
    let h = world_hit(world, far);
    assert_eq!((h.t, h.prim, h.geometry, h.instance), (5.0, 0, 1, 2));

    // Refits: the new geometry up by 2 (t = 3); the first one down by 1, both its instances.
    assert_eq!(refit_square(world, 1, 2.0), (QvStatus::Ok, String::new()));
    assert_eq!(world_hit(world, far).t, 3.0);
    assert_eq!(refit_square(world, 0, -1.0), (QvStatus::Ok, String::new()));
    let h = world_hit(world, down(2.25, 0.75));
    assert_eq!((h.t, h.prim, h.geometry, h.instance), (6.0, 1, 0, 1));
    assert_eq!(world_hit(world, down(0.75, 0.25)).t, 6.0);

    // Refused refits change nothing.
    let check_unchanged = || {
        assert_eq!(world_hit(world, far).t, 3.0);
        assert_eq!(world_hit(world, down(0.25, 0.75)).t, 6.0);
    };
    let (s, msg) = refit_square(world, 9, 0.0);
    assert_eq!(s, QvStatus::InvalidArgument);
    assert_eq!(
        msg,
        "qv_world_refit_mesh: geometry: 9 does not exist (the world has 2)"
    );
    let mut bad = SQUARE;
    bad[3][2] = f32::NAN;
    // SAFETY: a live handle; packed vertices, or a NULL, or too few for the indices.
    unsafe {
        assert_eq!(
            qv_world_refit_mesh(world, 0, bad.as_ptr().cast(), 4, 12),
            QvStatus::BadMesh
        );
        assert!(last_error().contains("vertex 3"), "{}", last_error());
        assert_eq!(
            qv_world_refit_mesh(world, 0, SQUARE.as_ptr().cast(), 2, 12),
            QvStatus::BadMesh
        );
        assert!(
            last_error().starts_with("qv_world_refit_mesh: vertices: geometry 0"),
            "{}",
            last_error()
        );
        assert_eq!(
            qv_world_refit_mesh(world, 0, SQUARE.as_ptr().cast(), 4, 8),
            QvStatus::BadMesh
        );
        assert_eq!(
            qv_world_refit_mesh(world, 0, null(), 4, 12),
            QvStatus::NullPointer
        );
        assert_eq!(last_error(), "qv_world_refit_mesh: vertices is NULL");
        assert_eq!(
            qv_world_refit_mesh(null_mut(), 0, SQUARE.as_ptr().cast(), 4, 12),
            QvStatus::NullPointer
        );
    }
    check_unchanged();

    // Refused additions add nothing: the next geometry is still 2.
    let (s, msg) = add_square(world, 0.0, &options(3, None)).unwrap_err();
    assert_eq!(s, QvStatus::InvalidArgument);
    assert!(msg.contains("options.quality"), "{msg}");
    let mut g2 = 7;
    // SAFETY: a live handle; a bad index, NULLs where refused.
    unsafe {
        let s = qv_world_add_mesh(
            world,
            SQUARE.as_ptr().cast(),
            4,
            12,
            [[0u32, 1, 4]].as_ptr().cast(),
            1,
            12,
            null(),
            &mut g2,
        );
        assert_eq!(s, QvStatus::BadMesh);
        assert!(last_error().contains("triangle 0"), "{}", last_error());
        let s = qv_world_add_mesh(
            world,
            SQUARE.as_ptr().cast(),
            4,
            12,
            INDICES.as_ptr().cast(),
            2,
            12,
            null(),
            null_mut(),
        );
        assert_eq!(s, QvStatus::NullPointer);
        assert_eq!(last_error(), "qv_world_add_mesh: geometry_id is NULL");
        let s = qv_world_add_mesh(
            null_mut(),
            SQUARE.as_ptr().cast(),
            4,
            12,
            INDICES.as_ptr().cast(),
            2,
            12,
            null(),
            &mut g2,
        );
        assert_eq!(s, QvStatus::NullPointer);
        assert_eq!(last_error(), "qv_world_add_mesh: world is NULL");
    }
    assert_eq!(g2, 7);
    check_unchanged();
    assert_eq!(add_square(world, 0.0, null()), Ok(2));
    // SAFETY: a live handle, freed once.
    unsafe { qv_world_free(world) };
}

#[test]
fn refit_mesh_is_refused_for_loaded_worlds_and_moving_meshes() {
    let dir = std::env::temp_dir().join(format!("quiver-capi-refit-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = std::ffi::CString::new(dir.join("w.qwld").to_str().unwrap()).unwrap();
    let world = two_squares(None, null_mut());
    let mut loaded = null_mut();
    // SAFETY: a live handle, a NUL-terminated path, a writable out.
    unsafe {
        assert_eq!(qv_world_save(world, path.as_ptr()), QvStatus::Ok);
        assert_eq!(qv_world_load(path.as_ptr(), &mut loaded), QvStatus::Ok);
    }
    let (s, msg) = refit_square(loaded, 0, 1.0);
    assert_eq!(s, QvStatus::InvalidArgument);
    assert!(msg.contains("keeps no index buffer"), "{msg}");
    assert!(msg.contains("loaded from a file"), "{msg}");
    assert_eq!(world_hit(loaded, down(0.25, 0.75)).t, 5.0);
    // A mesh added to the loaded world keeps its indices: it refits.
    let g = add_square(loaded, 0.0, null()).unwrap();
    assert_eq!(g, 1);
    let mut i = 0;
    let at5 = [1., 0., 0., 5., 0., 1., 0., 0., 0., 0., 1., 0.];
    // SAFETY: a live handle, a 12-float transform, a writable id.
    unsafe {
        assert_eq!(
            qv_world_add_instance(loaded, g, at5.as_ptr(), u32::MAX, &mut i),
            QvStatus::Ok
        );
    }
    assert_eq!(refit_square(loaded, g, 2.0), (QvStatus::Ok, String::new()));
    assert_eq!(world_hit(loaded, down(5.75, 0.25)).t, 3.0);

    // A moving mesh is not refit by qv_world_refit_mesh.
    let (mut b, mut moving) = (null_mut(), null_mut());
    // SAFETY: live handles, buffers as long as their counts, writable outs.
    unsafe {
        assert_eq!(qv_world_builder_new(&mut b), QvStatus::Ok);
        let g = add_moving(b, &moving_square(), 4, 3, &INDICES).unwrap();
        assert_eq!(
            qv_world_builder_add_instance(b, g, IDENTITY.as_ptr(), 1, &mut i),
            QvStatus::Ok
        );
        assert_eq!(qv_world_build(b, &mut moving), QvStatus::Ok);
    }
    let (s, msg) = refit_square(moving, 0, 1.0);
    assert_eq!(s, QvStatus::InvalidArgument);
    assert!(msg.contains("moving mesh"), "{msg}");
    // SAFETY: live handles, freed once.
    unsafe {
        qv_world_free(world);
        qv_world_free(loaded);
        qv_world_free(moving);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
