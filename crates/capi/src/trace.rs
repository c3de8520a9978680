//! Ray queries shared by BVHs and worlds: the bodies of `qv_bvh_*` and `qv_world_*`'s
//! `closest_hit`, `any_hit`, `closest_hits` and `any_hits`, for one ray, or for an array of
//! rays traced in parallel chunks on rayon's global pool, each chunk as packets where its rays
//! are coherent.

use crate::buffers::{input, output};
use crate::error::{guard, non_null, Failure, QvStatus};
use crate::types::{QvHit, QvRay};
use quiver_rt::rayon::prelude::*;
use quiver_rt::{Ray, RayQuery};
use std::ffi::c_int;
use std::mem::MaybeUninit;

/// Rays per parallel task: four packets, enough work to pay for a task.
const CHUNK: usize = 4 * quiver_rt::traverse::PACKET_RAYS;

/// A handle C can trace rays through: what it answers with and how its hits reach C.
pub(crate) trait Traced {
    /// The handle's argument name in messages (`"bvh"`, `"world"`).
    const ARGUMENT: &'static str;
    /// What answers the rays.
    type Scene: RayQuery + Sync;
    /// The scene behind the handle.
    fn scene(&self) -> &Self::Scene;
    /// A hit as C reads it (the miss record for `None`).
    fn to_c(hit: Option<<Self::Scene as RayQuery>::Hit>) -> QvHit;
}

/// The object behind handle `h`.
///
/// # Safety
/// `h` is NULL or a live handle (a `Box<H>` as a raw pointer) no thread changes during the
/// call.
unsafe fn scene<'a, H: Traced + 'a>(h: *const H) -> Result<&'a H::Scene, Failure> {
    non_null(h, H::ARGUMENT)?;
    // SAFETY: not NULL (checked); a live handle not changed meanwhile (the caller's contract).
    Ok(unsafe { &*h }.scene())
}

/// The closest hit of `*ray` into `*hit`: `qv_*_closest_hit` as `name`.
///
/// # Safety
/// `h` a live handle or NULL; `ray` readable and `hit` writable, or NULL.
pub(crate) unsafe fn closest_hit<H: Traced>(
    name: &str,
    h: *const H,
    ray: *const QvRay,
    hit: *mut QvHit,
) -> QvStatus {
    guard(name, || {
        // SAFETY: the caller's contract for each pointer, one element each.
        let (s, ray, hit) = unsafe { (scene(h)?, input(ray, 1, "ray")?, output(hit, 1, "hit")?) };
        hit[0].write(H::to_c(s.closest_hit(&ray[0].to_ray())));
        Ok(())
    })
}

/// Whether anything is hit within `*ray`'s interval, `*occluded` 1 or 0: `qv_*_any_hit` as
/// `name`.
///
/// # Safety
/// `h` a live handle or NULL; `ray` readable and `occluded` writable, or NULL.
pub(crate) unsafe fn any_hit<H: Traced>(
    name: &str,
    h: *const H,
    ray: *const QvRay,
    occluded: *mut c_int,
) -> QvStatus {
    guard(name, || {
        // SAFETY: the caller's contract for each pointer, one element each.
        let (s, ray, occluded) = unsafe {
            (
                scene(h)?,
                input(ray, 1, "ray")?,
                output(occluded, 1, "occluded")?,
            )
        };
        occluded[0].write(c_int::from(s.any_hit(&ray[0].to_ray())));
        Ok(())
    })
}

/// The closest hits of `n` rays into `hits[0..n]`, in parallel: `qv_*_closest_hits` as
/// `name`.
///
/// # Safety
/// `h` a live handle or NULL; `rays` readable and `hits` writable for `n` elements, not
/// overlapping, or NULL.
pub(crate) unsafe fn closest_hits<H: Traced>(
    name: &str,
    h: *const H,
    rays: *const QvRay,
    n: usize,
    hits: *mut QvHit,
) -> QvStatus
where
    <H::Scene as RayQuery>::Hit: Send,
{
    guard(name, || {
        // SAFETY: the caller's contract for each pointer, `n` elements each.
        let (s, rays, hits) =
            unsafe { (scene(h)?, input(rays, n, "rays")?, output(hits, n, "hits")?) };
        in_chunks(
            rays,
            hits,
            |rays, answers| s.closest_hit_packet(rays, answers),
            H::to_c,
        );
        Ok(())
    })
}

/// Whether each of `n` rays hits anything, `occluded[i]` 1 or 0, in parallel:
/// `qv_*_any_hits` as `name`.
///
/// # Safety
/// `h` a live handle or NULL; `rays` readable and `occluded` writable for `n` elements, not
/// overlapping, or NULL.
pub(crate) unsafe fn any_hits<H: Traced>(
    name: &str,
    h: *const H,
    rays: *const QvRay,
    n: usize,
    occluded: *mut u8,
) -> QvStatus {
    guard(name, || {
        // SAFETY: the caller's contract for each pointer, `n` elements each.
        let (s, rays, occluded) = unsafe {
            (
                scene(h)?,
                input(rays, n, "rays")?,
                output(occluded, n, "occluded")?,
            )
        };
        in_chunks(
            rays,
            occluded,
            |rays, answers| s.any_hit_packet(rays, answers),
            u8::from,
        );
        Ok(())
    })
}

/// Every ray's answer into `out` (as long as `rays`): chunks in parallel, each traced by
/// `trace` into its answers, each answer converted by `to_c`.
fn in_chunks<A: Clone + Default + Send, O: Send>(
    rays: &[QvRay],
    out: &mut [MaybeUninit<O>],
    trace: impl Fn(&[Ray], &mut [A]) + Sync,
    to_c: fn(A) -> O,
) {
    rays.par_chunks(CHUNK)
        .zip(out.par_chunks_mut(CHUNK))
        .for_each(|(rays, slots)| {
            let rays: Vec<Ray> = rays.iter().map(|r| r.to_ray()).collect();
            let mut answers = vec![A::default(); rays.len()];
            trace(&rays, &mut answers);
            for (slot, answer) in slots.iter_mut().zip(answers) {
                slot.write(to_c(answer));
            }
        });
}
