//! Bit masks of rays and lanes: the set bits, lowest first.

/// Set bits of a mask (packet or lane mask), lowest first.
#[inline(always)]
pub(crate) fn bits(mask: impl Into<u64>) -> impl Iterator<Item = usize> {
    let mut m = mask.into();
    std::iter::from_fn(move || {
        (m != 0).then(|| {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            i
        })
    })
}

#[cfg(test)]
mod tests {
    use super::bits;

    #[test]
    fn bits_lists_set_bits_lowest_first() {
        assert_eq!(bits(0u64).count(), 0);
        assert_eq!(bits(0b1011_0001u32).collect::<Vec<_>>(), vec![0, 4, 5, 7]);
        assert_eq!(bits(u64::MAX).count(), 64);
        assert_eq!(bits(1u64 << 63).collect::<Vec<_>>(), vec![63]);
    }
}
