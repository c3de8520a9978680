//! Space-filling-curve order of primitives for the clustering builders: 63-bit Morton codes
//! (21 bits per axis over the centroid bounds) or the 64-bit *extended* Morton codes of
//! Vinkler et al. 2017 in their variable form (EMC-64-var, the thesis's fourth phase): every
//! seventh bit encodes the primitive's size (its box diagonal over the scene's), and each
//! other bit halves whichever axis of the scene is currently longest, so a flat or long scene
//! spends its bits where it extends.
//!
//! The sort key is (code, primitive index): unique, so the order is the same for any number
//! of threads.

use crate::geometry::Aabb;
use glam::Vec3A;
use rayon::prelude::*;

/// Which code orders the primitives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Curve {
    /// Plain Morton code: x, y, z bits alternating, 21 each.
    Morton,
    /// EMC-64-var: size every seventh bit, the other bits by longest remaining axis.
    Extended,
}

/// The primitives `idx` sorted along `curve`, and their codes in that order.
pub(crate) fn sorted(bounds: &[Aabb], idx: &[u32], curve: Curve) -> (Vec<u32>, Vec<u64>) {
    let (scene, diag) = idx
        .par_chunks(16 * 1024)
        .map(|ch| {
            ch.iter().fold((Aabb::EMPTY, 0f32), |(mut c, d), &i| {
                let b = &bounds[i as usize];
                c.grow(b.center());
                (c, d.max((b.max - b.min).length()))
            })
        })
        .reduce(
            || (Aabb::EMPTY, 0f32),
            |a, b| (a.0.union(&b.0), a.1.max(b.1)),
        );
    let layout = match curve {
        Curve::Morton => BitLayout::morton(),
        Curve::Extended => BitLayout::extended(scene.extent()),
    };
    let enc = Encoder::new(&scene, diag, &layout);
    let mut keyed: Vec<(u64, u32)> = idx
        .par_iter()
        .map(|&i| (enc.code(&bounds[i as usize]), i))
        .collect();
    keyed.par_sort_unstable();
    keyed.into_par_iter().map(|(c, i)| (i, c)).unzip()
}

/// Which quantity each code bit takes its next bit from, most significant first.
struct BitLayout {
    /// 0, 1, 2: an axis; 3: the size.
    source: Vec<u8>,
}

const SIZE: u8 = 3;

impl BitLayout {
    fn morton() -> Self {
        BitLayout {
            source: (0..63).map(|b| (b % 3) as u8).collect(),
        }
    }

    /// 64 bits; every seventh a size bit, the others halving the longest remaining axis
    /// (ties to the lower axis, so a point-like scene falls back to x, y, z order).
    fn extended(extent: Vec3A) -> Self {
        let mut e = extent;
        let source = (0..64)
            .map(|b| {
                if b % 7 == 6 {
                    return SIZE;
                }
                let axis = if e.x >= e.y && e.x >= e.z {
                    0
                } else if e.y >= e.z {
                    1
                } else {
                    2
                };
                if e.max_element() == 0.0 {
                    // No extent at all: keep alternating instead of spending every bit on x.
                    return (b % 3) as u8;
                }
                e[axis] *= 0.5;
                axis as u8
            })
            .collect();
        BitLayout { source }
    }

    fn bits(&self, q: u8) -> u32 {
        self.source.iter().filter(|&&s| s == q).count() as u32
    }
}

/// Quantises a primitive's centroid and size and interleaves them by a [`BitLayout`].
struct Encoder<'a> {
    origin: Vec3A,
    /// 2^bits / extent per axis (0 for an axis without extent).
    scale: [f64; 3],
    /// 2^bits / the largest primitive diagonal (0 when all are points).
    size_scale: f64,
    /// Bits per quantity (x, y, z, size).
    bits: [u32; 4],
    layout: &'a BitLayout,
}

impl<'a> Encoder<'a> {
    fn new(scene: &Aabb, max_diag: f32, layout: &'a BitLayout) -> Self {
        let bits = [0, 1, 2, SIZE].map(|q| layout.bits(q));
        let e = scene.extent();
        let scale = [0, 1, 2].map(|a| {
            if e[a] > 0.0 {
                (bits[a] as f64).exp2() / e[a] as f64
            } else {
                0.0
            }
        });
        let size_scale = if max_diag > 0.0 {
            (bits[3] as f64).exp2() / max_diag as f64
        } else {
            0.0
        };
        Encoder {
            origin: scene.min,
            scale,
            size_scale,
            bits,
            layout,
        }
    }

    /// Quantised value of `x` in `0 .. 2^bits` (the cast saturates: the top edge and any
    /// rounding past it land in the last cell).
    fn cell(x: f64, bits: u32) -> u64 {
        let top = if bits >= 64 {
            u64::MAX
        } else {
            (1u64 << bits) - 1
        };
        (x.max(0.0) as u64).min(top)
    }

    fn code(&self, b: &Aabb) -> u64 {
        let c = b.center() - self.origin;
        let size = (b.max - b.min).length() as f64;
        let q = [
            Self::cell(c.x as f64 * self.scale[0], self.bits[0]),
            Self::cell(c.y as f64 * self.scale[1], self.bits[1]),
            Self::cell(c.z as f64 * self.scale[2], self.bits[2]),
            Self::cell(size * self.size_scale, self.bits[3]),
        ];
        // Each quantity gives its bits most significant first, in the layout's order.
        let mut left = self.bits;
        let mut code = 0u64;
        for &s in &self.layout.source {
            left[s as usize] -= 1;
            code = (code << 1) | ((q[s as usize] >> left[s as usize]) & 1);
        }
        code
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// The box of one point, for builder tests over centroids.
    pub(in crate::builders) fn point(x: f32, y: f32, z: f32) -> Aabb {
        let p = Vec3A::new(x, y, z);
        Aabb::new(p, p)
    }

    #[test]
    fn morton_orders_corners_x_bit_first() {
        // Corner i of the unit cube has x = bit 0, y = bit 1, z = bit 2 of i. The code's top
        // bits are x, y, z of the corner, so the curve visits them ordered by (x, y, z).
        let boxes: Vec<Aabb> = (0..8)
            .map(|i| point((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32))
            .collect();
        let idx: Vec<u32> = (0..8).collect();
        let (order, _) = sorted(&boxes, &idx, Curve::Morton);
        assert_eq!(order, vec![0, 4, 2, 6, 1, 5, 3, 7]);
    }

    #[test]
    fn extended_layout_follows_the_longest_axis() {
        // A scene 8 times longer in x than in y and z: the first three spatial bits halve x
        // (8 → 4 → 2 → 1), then the axes alternate; bit 7 is a size bit.
        let l = BitLayout::extended(Vec3A::new(8.0, 1.0, 1.0));
        assert_eq!(&l.source[..7], &[0, 0, 0, 0, 1, 2, SIZE]);
        assert_eq!(l.source.len(), 64);
        assert_eq!(l.bits(SIZE), 9);
    }

    #[test]
    fn extended_puts_small_before_large_at_one_place() {
        // Same centroid, different sizes: the size bits order them by diagonal.
        let c = Vec3A::splat(0.5);
        let boxes: Vec<Aabb> = [0.4f32, 0.1, 0.3, 0.2]
            .iter()
            .map(|&h| Aabb::new(c - Vec3A::splat(h), c + Vec3A::splat(h)))
            .collect();
        let (order, _) = sorted(&boxes, &[0, 1, 2, 3], Curve::Extended);
        assert_eq!(order, vec![1, 3, 2, 0]);
    }
}
