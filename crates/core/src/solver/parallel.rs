//! Sharing arrays between rayon tasks that write disjoint parts of them.
//!
//! Two patterns need it: G2P and the stress update write disjoint particle ranges, and P2G
//! writes grid slabs that the colouring keeps apart. Each use states why its writes are
//! disjoint.

use std::ops::Range;

/// A raw pointer to the start of a slice, shareable across threads.
pub(crate) struct SharedSlice<T> {
    ptr: *mut T,
    len: usize,
}

// Copy whatever T is: the wrapper is a pointer and a length (derive would ask T: Copy).
impl<T> Clone for SharedSlice<T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for SharedSlice<T> {}

// SAFETY: the wrapper only hands out access through the unsafe methods below, whose callers
// guarantee that no two threads touch the same element.
unsafe impl<T: Send> Send for SharedSlice<T> {}
unsafe impl<T: Send> Sync for SharedSlice<T> {}

impl<T> SharedSlice<T> {
    /// Wraps a slice; the borrow must outlive every use of the wrapper.
    pub(crate) fn new(slice: &mut [T]) -> Self {
        Self {
            ptr: slice.as_mut_ptr(),
            len: slice.len(),
        }
    }

    /// A mutable sub-slice.
    ///
    /// # Safety
    /// No other live reference may overlap `range`, and the wrapped slice must still be alive.
    #[inline(always)]
    pub(crate) unsafe fn range<'a>(self, range: Range<usize>) -> &'a mut [T] {
        if range.is_empty() {
            return &mut [];
        }
        assert!(range.end <= self.len, "shared slice range out of bounds");
        // SAFETY: in bounds (checked above); exclusivity is the caller's guarantee.
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(range.start), range.len()) }
    }

    /// One element, mutably.
    ///
    /// # Safety
    /// No other thread may access element `i` at the same time; `i < len`.
    #[inline(always)]
    pub(crate) unsafe fn get<'a>(self, i: usize) -> &'a mut T {
        debug_assert!(i < self.len);
        // SAFETY: the caller guarantees bounds and exclusivity.
        unsafe { &mut *self.ptr.add(i) }
    }
}

/// Particles per rayon task in particle-parallel passes.
pub(crate) const PARTICLE_CHUNK: usize = 2048;

/// The chunk ranges of `0..n`.
pub(crate) fn chunk_range(chunk: usize, n: usize) -> Range<usize> {
    let start = chunk * PARTICLE_CHUNK;
    start..(start + PARTICLE_CHUNK).min(n)
}

/// Number of chunks covering `0..n`.
pub(crate) fn chunk_count(n: usize) -> usize {
    n.div_ceil(PARTICLE_CHUNK)
}

/// Reduces `map(0) ⊕ … ⊕ map(count − 1)` in parallel along a merge tree fixed by `count`
/// alone (halves, down to single items), so floating-point sums come out the same bit for
/// bit whichever threads ran which part; rayon's own `reduce` merges in the order tasks
/// finish, which left energy sums differing in their last bit between identical runs.
pub(crate) fn ordered_reduce<T, M, R>(count: usize, identity: fn() -> T, map: M, merge: R) -> T
where
    T: Send,
    M: Fn(usize) -> T + Sync,
    R: Fn(T, T) -> T + Sync,
{
    fn go<T: Send>(
        range: Range<usize>,
        map: &(impl Fn(usize) -> T + Sync),
        merge: &(impl Fn(T, T) -> T + Sync),
    ) -> T {
        if range.len() == 1 {
            return map(range.start);
        }
        let mid = range.start + range.len() / 2;
        let (a, b) = rayon::join(
            || go(range.start..mid, map, merge),
            || go(mid..range.end, map, merge),
        );
        merge(a, b)
    }
    if count == 0 {
        return identity();
    }
    go(0..count, &map, &merge)
}

/// The sum of `term(p)` over the particles `0..n`, chunk by chunk in the fixed order of
/// [`ordered_reduce`].
pub(crate) fn ordered_particle_sum(n: usize, term: impl Fn(usize) -> f64 + Sync) -> f64 {
    ordered_reduce(
        chunk_count(n),
        || 0.0,
        |chunk| chunk_range(chunk, n).map(&term).sum::<f64>(),
        |a, b| a + b,
    )
}
