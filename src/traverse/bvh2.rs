//! Single-ray traversal of the depth-first [`Bvh2`].

use super::{SlabRay, FAR_SLACK};
use crate::build::MAX_DEPTH;
use crate::geometry::{Hit, Ray};
use crate::layout::{Bvh2, Bvh2Node};
use std::ops::Range;

/// The node's box as eight floats: min at 0..3, max at 4..7.
#[inline(always)]
fn planes(n: &Bvh2Node) -> &[f32; 8] {
    bytemuck::cast_ref(n)
}

impl Bvh2 {
    /// The nearest hit along `ray` (lowest primitive index on ties): exactly what
    /// [`crate::reference::closest_hit`] returns for the same triangles.
    pub fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        let mut best = Hit {
            t: ray.t_max,
            prim: u32::MAX,
            u: 0.0,
            v: 0.0,
        };
        self.traverse(ray, |range, limit| {
            let r = Ray {
                t_max: *limit,
                ..*ray
            };
            for i in range {
                if let Some(h) = self.tris[i].intersect(&r) {
                    let prim = self.prim_ids[i];
                    if best.is_beaten_by(h.t, prim) {
                        best = Hit {
                            t: h.t,
                            prim,
                            u: h.u,
                            v: h.v,
                        };
                    }
                }
            }
            *limit = best.t;
            false
        });
        (best.prim != u32::MAX).then_some(best)
    }

    /// True when anything is hit within the ray's interval; stops at the first hit.
    pub fn any_hit(&self, ray: &Ray) -> bool {
        let mut hit = false;
        self.traverse(ray, |range, _| {
            hit = self.tris[range].iter().any(|t| t.intersect(ray).is_some());
            hit
        });
        hit
    }

    /// Visits the leaves the ray may hit, nearest box first. `leaf(triangles, t_limit)` tests
    /// a leaf, may lower `t_limit` (boxes entered beyond it are skipped; a box entered exactly
    /// at it is still visited, so ties are seen) and returns true to stop.
    #[inline(always)]
    fn traverse<F>(&self, ray: &Ray, mut leaf: F)
    where
        F: FnMut(Range<usize>, &mut f32) -> bool,
    {
        let sr = SlabRay::new(ray);
        let nodes = self.nodes.as_slice();
        let mut limit = ray.t_max;
        let mut stack = [(0u32, 0f32); MAX_DEPTH + 1];
        let mut sp = 0;
        let mut node = 0usize;
        if sr.enter(planes(&nodes[0]), limit).is_none() {
            return;
        }
        loop {
            let n = &nodes[node];
            if n.is_leaf() {
                let first = n.link as usize;
                if leaf(first..first + n.prim_count() as usize, &mut limit) {
                    return;
                }
            } else {
                let (l, r) = (node + 1, n.link as usize);
                let bound = limit * FAR_SLACK;
                let tl = sr.enter(planes(&nodes[l]), bound);
                let tr = sr.enter(planes(&nodes[r]), bound);
                match (tl, tr) {
                    (Some(a), Some(b)) => {
                        let (near, far, t_far) = if a <= b { (l, r, b) } else { (r, l, a) };
                        stack[sp] = (far as u32, t_far);
                        sp += 1;
                        node = near;
                        continue;
                    }
                    (Some(_), None) => {
                        node = l;
                        continue;
                    }
                    (None, Some(_)) => {
                        node = r;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // Pop the next box still worth entering.
            loop {
                if sp == 0 {
                    return;
                }
                sp -= 1;
                let (i, t) = stack[sp];
                if t <= limit * FAR_SLACK {
                    node = i as usize;
                    break;
                }
            }
        }
    }
}
