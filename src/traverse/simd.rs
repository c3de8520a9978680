//! Small pieces every kernel shares: NaN-aware SIMD min/max, bit-mask iteration, and the
//! farthest-first order a stack is filled in.

pub(crate) use crate::mask::bits;
use wide::{f32x4, f32x8};

/// `max` and `min` where the first operand may be NaN and the second never is: a NaN slab
/// distance (a zero direction component with the origin exactly on the plane) must never
/// limit a ray's interval, so it yields the second operand.
pub(crate) trait NanFirst: Sized {
    /// `max(self, b)`, or `b` where `self` is NaN.
    fn max_nan_first(self, b: Self) -> Self;
    /// `min(self, b)`, or `b` where `self` is NaN.
    fn min_nan_first(self, b: Self) -> Self;
}

macro_rules! nan_first {
    ($($t:ty),*) => {$(
        impl NanFirst for $t {
            #[inline(always)]
            fn max_nan_first(self, b: Self) -> Self {
                // MAXPS/MINPS return their second operand when either is NaN.
                #[cfg(target_feature = "sse")]
                {
                    self.fast_max(b)
                }
                #[cfg(not(target_feature = "sse"))]
                {
                    b.max(self)
                }
            }
            #[inline(always)]
            fn min_nan_first(self, b: Self) -> Self {
                #[cfg(target_feature = "sse")]
                {
                    self.fast_min(b)
                }
                #[cfg(not(target_feature = "sse"))]
                {
                    b.min(self)
                }
            }
        }
    )*};
}
nan_first!(f32x4, f32x8);

/// Inserts `(t, item)` into `list[..len]`, which is kept in decreasing order of distance: the
/// order a traversal stack must receive a node's children in so that the nearest is popped
/// first. Equal distances keep their arrival order. (The caller keeps the array and its
/// length in locals, so both stay in registers: a struct around them measured ~10% more
/// instructions in the node loop under callgrind.)
///
/// # Panics
/// When `list` is full (`len == list.len()`).
#[inline(always)]
pub(crate) fn insert_farthest_first<T: Copy>(list: &mut [(f32, T)], len: usize, t: f32, item: T) {
    let mut j = len;
    while j > 0 && list[j - 1].0 < t {
        list[j] = list[j - 1];
        j -= 1;
    }
    list[j] = (t, item);
}

/// Inserts `key` into `list[..len]`, kept in decreasing order (an 8-wide node's children,
/// farthest first, as keys that compare as integers).
///
/// # Panics
/// When `list` is full (`len == list.len()`).
#[inline(always)]
pub(crate) fn insert_descending(list: &mut [u32], len: usize, key: u32) {
    let mut j = len;
    while j > 0 && list[j - 1] < key {
        list[j] = list[j - 1];
        j -= 1;
    }
    list[j] = key;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nan_first_ignores_a_nan_first_operand_in_every_lane() {
        let a = f32x8::from([f32::NAN, 1.0, -1.0, f32::NAN, 5.0, 0.0, -0.0, f32::INFINITY]);
        let b = f32x8::from([2.0, 3.0, -2.0, -7.0, 4.0, 0.0, 0.0, 1.0]);
        assert_eq!(
            a.max_nan_first(b).to_array(),
            [2.0, 3.0, -1.0, -7.0, 5.0, 0.0, 0.0, f32::INFINITY]
        );
        assert_eq!(
            a.min_nan_first(b).to_array(),
            [2.0, 1.0, -2.0, -7.0, 4.0, 0.0, 0.0, 1.0]
        );
        let a4 = f32x4::from([f32::NAN, 1.0, 2.0, f32::NAN]);
        let b4 = f32x4::from([0.5, 0.5, 3.0, f32::NEG_INFINITY]);
        assert_eq!(
            a4.max_nan_first(b4).to_array(),
            [0.5, 1.0, 3.0, f32::NEG_INFINITY]
        );
        assert_eq!(
            a4.min_nan_first(b4).to_array(),
            [0.5, 0.5, 2.0, f32::NEG_INFINITY]
        );
    }

    #[test]
    fn farthest_first_orders_by_decreasing_distance_stably() {
        let mut list = [(0.0, 0u8); 4];
        for (k, (t, i)) in [(1.0, 0), (3.0, 1), (1.0, 2), (2.0, 3)]
            .into_iter()
            .enumerate()
        {
            insert_farthest_first(&mut list, k, t, i);
        }
        assert_eq!(list.map(|x| x.1), [1, 3, 0, 2]);
    }
}
