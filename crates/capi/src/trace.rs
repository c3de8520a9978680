//! Ray queries shared by BVHs and worlds: one ray, or an array of rays traced in parallel
//! chunks on rayon's global pool, each chunk as packets where its rays are coherent.

use crate::types::{QvHit, QvRay};
use quiver_rt::rayon::prelude::*;
use quiver_rt::{Ray, RayQuery};
use std::mem::MaybeUninit;

/// Rays per parallel task: four packets, enough work to pay for a task.
const CHUNK: usize = 4 * quiver_rt::traverse::PACKET_RAYS;

/// The core's rays for `rays`.
fn to_rays(rays: &[QvRay]) -> Vec<Ray> {
    rays.iter().map(|r| r.to_ray()).collect()
}

/// The closest hit of every ray into `hits` (as long as `rays`), each converted by `convert`.
pub(crate) fn closest_hits<Q>(
    scene: &Q,
    rays: &[QvRay],
    hits: &mut [MaybeUninit<QvHit>],
    convert: fn(Option<Q::Hit>) -> QvHit,
) where
    Q: RayQuery + Sync,
    Q::Hit: Send,
{
    rays.par_chunks(CHUNK)
        .zip(hits.par_chunks_mut(CHUNK))
        .for_each(|(rays, slots)| {
            let rays = to_rays(rays);
            let mut answers = vec![None; rays.len()];
            scene.closest_hit_packet(&rays, &mut answers);
            for (slot, answer) in slots.iter_mut().zip(answers) {
                slot.write(convert(answer));
            }
        });
}

/// Whether each ray hits anything within its interval, into `occluded` (1 or 0; as long as
/// `rays`).
pub(crate) fn any_hits<Q: RayQuery + Sync>(
    scene: &Q,
    rays: &[QvRay],
    occluded: &mut [MaybeUninit<u8>],
) {
    rays.par_chunks(CHUNK)
        .zip(occluded.par_chunks_mut(CHUNK))
        .for_each(|(rays, slots)| {
            let rays = to_rays(rays);
            let mut answers = vec![false; rays.len()];
            scene.any_hit_packet(&rays, &mut answers);
            for (slot, answer) in slots.iter_mut().zip(answers) {
                slot.write(u8::from(answer));
            }
        });
}
