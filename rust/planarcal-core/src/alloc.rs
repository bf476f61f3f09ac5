//! Allocations proportional to the input, made fallibly: a buffer the allocator refuses (an
//! address-space limit, a container's memory cap) is [`HomographyError::OutOfMemory`], which
//! the bindings raise as MemoryError, rather than Rust's abort of the whole process. Every
//! buffer of a batch entry point that grows with the number of points comes from here; small
//! fixed-size ones (a 3 x 3 system, a 64-sample batch) need not.

use crate::error::{HomographyError, Result};

/// The error for `count` elements of `T` that could not be allocated.
pub fn out_of_memory<T>(count: usize) -> HomographyError {
    HomographyError::OutOfMemory {
        bytes: count.saturating_mul(std::mem::size_of::<T>()),
    }
}

/// An empty vector with room for `count` elements.
pub fn with_capacity<T>(count: usize) -> Result<Vec<T>> {
    let mut v = Vec::new();
    reserve(&mut v, count)?;
    Ok(v)
}

/// Room for `more` elements beyond `v`'s length.
pub fn reserve<T>(v: &mut Vec<T>, more: usize) -> Result<()> {
    v.try_reserve_exact(more)
        .map_err(|_| out_of_memory::<T>(v.len().saturating_add(more)))
}

/// `count` copies of `value`.
pub fn filled<T: Clone>(value: T, count: usize) -> Result<Vec<T>> {
    let mut v = with_capacity(count)?;
    v.resize(count, value);
    Ok(v)
}

/// The items of `iter`, in room reserved for as many as it can yield (its size hint's upper
/// bound, else its lower one).
pub fn collect<T>(iter: impl IntoIterator<Item = T>) -> Result<Vec<T>> {
    let iter = iter.into_iter();
    let (low, high) = iter.size_hint();
    let mut v = with_capacity(high.unwrap_or(low))?;
    for item in iter {
        if v.len() == v.capacity() {
            let more = v.len().max(1);
            reserve(&mut v, more)?;
        }
        v.push(item);
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_buffer_too_large_is_an_error_not_an_abort() {
        let e = with_capacity::<[f64; 2]>(usize::MAX / 4).unwrap_err();
        assert_eq!(e, HomographyError::OutOfMemory { bytes: usize::MAX });
        assert!(filled(0u8, isize::MAX as usize).is_err());
        assert_eq!(filled(7u32, 3).unwrap(), vec![7, 7, 7]);
        let evens = collect((0..10).filter(|i| i % 2 == 0)).unwrap();
        assert_eq!(evens, vec![0, 2, 4, 6, 8]);
        assert!(!e.is_invalid_argument() && !e.is_degenerate());
    }
}
