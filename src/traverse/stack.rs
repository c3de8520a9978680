//! The walks' traversal stack.

/// A fixed-capacity stack that is not initialised up front: zeroing a traversal stack of a few
/// hundred entries per ray cost more than the traversal of a small scene.
pub(crate) struct Stack<T: Copy, const N: usize> {
    items: [std::mem::MaybeUninit<T>; N],
    len: usize,
}

impl<T: Copy, const N: usize> Stack<T, N> {
    #[inline(always)]
    pub fn new() -> Self {
        Stack {
            // A const block, not `[MaybeUninit::uninit(); N]`: with debug info on, rustc 1.95
            // zeroes the latter with a memset (13,776 bytes per point walk's stack).
            items: [const { std::mem::MaybeUninit::uninit() }; N],
            len: 0,
        }
    }

    /// Pushes `x`. Capacities come from the tree depth bound, so overflow is a bug: it panics
    /// (bounds check) rather than corrupting memory.
    #[inline(always)]
    pub fn push(&mut self, x: T) {
        self.items[self.len] = std::mem::MaybeUninit::new(x);
        self.len += 1;
    }

    /// How many entries it holds.
    #[inline(always)]
    pub fn len(&self) -> usize {
        self.len
    }

    /// The entries pushed since the stack held `from` (all of them when `from` is 0), to
    /// reorder in place.
    #[inline(always)]
    pub fn above_mut(&mut self, from: usize) -> &mut [T] {
        let items = &mut self.items[from.min(self.len)..self.len];
        // SAFETY: every slot below `len` was written by `push`; `MaybeUninit<T>` has `T`'s
        // layout, so the initialised slots are a `[T]`.
        unsafe { &mut *(items as *mut [std::mem::MaybeUninit<T>] as *mut [T]) }
    }

    #[inline(always)]
    pub fn pop(&mut self) -> Option<T> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: every slot below `len` was written by `push` and `len` only shrinks here.
        Some(unsafe { self.items[self.len].assume_init() })
    }
}

#[cfg(test)]
mod tests {
    use super::Stack;

    #[test]
    fn stack_returns_what_was_pushed_last_in_first_out() {
        let mut s: Stack<(u32, f32), 4> = Stack::new();
        assert_eq!(s.pop(), None);
        for i in 0..4 {
            s.push((i, i as f32));
        }
        assert_eq!(s.pop(), Some((3, 3.0)));
        s.push((9, 9.0));

        let rest: Vec<u32> = std::iter::from_fn(|| s.pop()).map(|x| x.0).collect();
        assert_eq!(rest, vec![9, 2, 1, 0]);
    }

    #[test]
    #[should_panic]
    fn stack_overflow_panics_instead_of_corrupting() {
        let mut s: Stack<u32, 2> = Stack::new();
        for i in 0..3 {
            s.push(i);
        }
    }
}
