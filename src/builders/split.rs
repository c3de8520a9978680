//! The partition helpers the top-down builders share: a set's bounds, the object-median
//! split, the widest axis.

use crate::geometry::Aabb;
use glam::Vec3A;

/// Bounds and centroid bounds of a set of primitives.
pub(crate) fn bounds_of(bounds: &[Aabb], idx: &[u32]) -> (Aabb, Aabb) {
    let mut b = Aabb::EMPTY;
    let mut c = Aabb::EMPTY;
    for &i in idx {
        let pb = bounds[i as usize];
        b = b.union(&pb);
        c.grow(pb.center());
    }
    (b, c)
}

/// Splits `idx` at its median along the widest centroid axis (ties broken by index, so the
/// result is a function of the input alone). Returns the size of the left half.
pub(crate) fn median_split(bounds: &[Aabb], idx: &mut [u32], centroid_bounds: &Aabb) -> usize {
    let axis = widest_axis(centroid_bounds.extent());
    idx.sort_unstable_by(|&a, &b| {
        let ca = bounds[a as usize].center()[axis];
        let cb = bounds[b as usize].center()[axis];
        ca.total_cmp(&cb).then(a.cmp(&b))
    });
    idx.len() / 2
}

pub(crate) fn widest_axis(e: Vec3A) -> usize {
    if e.x >= e.y && e.x >= e.z {
        0
    } else if e.y >= e.z {
        1
    } else {
        2
    }
}
