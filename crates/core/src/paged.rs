//! Zero-initialised arrays whose memory is taken from the operating system page by page as
//! they are written: the storage of the sparse grid.
//!
//! A [`PagedArray`] reserves address space for its whole length (an anonymous mapping with
//! no swap reservation) but the kernel backs a page with memory only when it is first
//! written; reading an untouched page reads zeros and costs no memory. [`PagedArray::release`]
//! zeroes a range and hands its whole pages back. So a grid as large as the domain costs
//! memory only where particles have been since their pages were last released: the
//! virtual-memory technique of SPGrid (Setaluri, Aanjaneya, Bauer and Sifakis, "SPGrid: a
//! sparse paged grid structure applied to adaptive smoke simulation", ACM TOG 33(6), 2014),
//! here over the grid's plain x-major node order. Where anonymous mappings are not
//! available (non-Unix targets) it is an ordinary zeroed allocation.

use crate::math::Vector;
use std::ops::{Deref, DerefMut, Range};

/// Element types whose all-zero bit pattern is the value zero, so that fresh and released
/// pages read as zeroed elements.
///
/// # Safety
/// The all-zero bit pattern must be a valid value of the type, with no drop glue.
pub unsafe trait Zeroable: Copy + Send + Sync + 'static {}

// SAFETY: f64 zero is all zero bits.
unsafe impl Zeroable for f64 {}
// SAFETY: nalgebra's statically sized vectors are arrays of f64.
unsafe impl<const D: usize> Zeroable for Vector<D> {}

/// A fixed-length array of zeroed `T` backed by pages taken on first write.
pub struct PagedArray<T: Zeroable> {
    ptr: *mut T,
    len: usize,
    /// Bytes of the mapping (0 for an empty array or the heap fallback).
    mapped: usize,
    /// The heap fallback, where there is no mapping.
    _heap: Vec<T>,
}

// SAFETY: the array owns its memory like a Vec does; T is Send + Sync.
unsafe impl<T: Zeroable> Send for PagedArray<T> {}
// SAFETY: shared access hands out only shared slices.
unsafe impl<T: Zeroable> Sync for PagedArray<T> {}

impl<T: Zeroable> PagedArray<T> {
    /// `len` zeroed elements; no memory is taken until they are written.
    pub fn zeroed(len: usize) -> Self {
        let bytes = len.saturating_mul(std::mem::size_of::<T>());
        if bytes == 0 {
            return Self::heap(Vec::new());
        }
        match map_zeroed(bytes) {
            Some(ptr) => Self {
                ptr: ptr.cast(),
                len,
                mapped: bytes,
                _heap: Vec::new(),
            },
            None => Self::heap(zeroed_vec(len)),
        }
    }

    fn heap(mut heap: Vec<T>) -> Self {
        Self {
            ptr: heap.as_mut_ptr(),
            len: heap.len(),
            mapped: 0,
            _heap: heap,
        }
    }

    /// Sets `range` to zero and returns the memory of the whole pages inside it to the
    /// operating system (the rest of the range is written with zeros).
    pub fn release(&mut self, range: Range<usize>) {
        let range = range.start.min(self.len)..range.end.min(self.len);
        if range.is_empty() {
            return;
        }
        let size = std::mem::size_of::<T>();
        if self.mapped > 0 {
            let page = page_size();
            let (start, end) = (range.start * size, range.end * size);
            let first = start.div_ceil(page) * page;
            let last = end / page * page;
            if first < last && unmap_pages(self.ptr.cast::<u8>(), first, last - first) {
                // The element ranges before `first` and after `last` still need zeros.
                self.zero_bytes(start, first);
                self.zero_bytes(last, end);
                return;
            }
        }
        let zero = zero_value::<T>();
        self[range].fill(zero);
    }

    /// Writes zeros over bytes `from..to` of the array (an element cut by a page boundary
    /// inside a released range gets its bytes on one side here, on the other from the
    /// released page).
    fn zero_bytes(&mut self, from: usize, to: usize) {
        if from < to {
            // SAFETY: in bounds of the mapping (from < to <= len·size); zero bytes are a valid
            // T (Zeroable), and element bytes are only overwritten by zeros.
            unsafe { std::ptr::write_bytes(self.ptr.cast::<u8>().add(from), 0, to - from) };
        }
    }
}

/// The zero value of a [`Zeroable`] type.
fn zero_value<T: Zeroable>() -> T {
    // SAFETY: all-zero bits are a valid T (Zeroable's contract).
    unsafe { std::mem::zeroed() }
}

fn zeroed_vec<T: Zeroable>(len: usize) -> Vec<T> {
    vec![zero_value::<T>(); len]
}

impl<T: Zeroable> Deref for PagedArray<T> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        if self.len == 0 {
            return &[];
        }
        // SAFETY: ptr points at len initialised (zeroed or written) elements we own.
        unsafe { std::slice::from_raw_parts(self.ptr, self.len) }
    }
}

impl<T: Zeroable> DerefMut for PagedArray<T> {
    fn deref_mut(&mut self) -> &mut [T] {
        if self.len == 0 {
            return &mut [];
        }
        // SAFETY: as for deref, and &mut self makes the access exclusive.
        unsafe { std::slice::from_raw_parts_mut(self.ptr, self.len) }
    }
}

impl<'a, T: Zeroable> IntoIterator for &'a PagedArray<T> {
    type Item = &'a T;
    type IntoIter = std::slice::Iter<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

impl<'a, T: Zeroable> IntoIterator for &'a mut PagedArray<T> {
    type Item = &'a mut T;
    type IntoIter = std::slice::IterMut<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter_mut()
    }
}

impl<T: Zeroable> Drop for PagedArray<T> {
    fn drop(&mut self) {
        if self.mapped > 0 {
            unmap(self.ptr.cast(), self.mapped);
        }
    }
}

#[cfg(unix)]
fn page_size() -> usize {
    use std::sync::OnceLock;
    static PAGE: OnceLock<usize> = OnceLock::new();
    // SAFETY: sysconf has no preconditions.
    *PAGE.get_or_init(|| match unsafe { libc::sysconf(libc::_SC_PAGESIZE) } {
        n if n > 0 => n as usize,
        _ => 4096,
    })
}

/// An anonymous private mapping of `bytes` zeroed bytes without swap reservation.
#[cfg(unix)]
fn map_zeroed(bytes: usize) -> Option<*mut u8> {
    #[cfg(any(target_os = "linux", target_os = "android"))]
    let flags = libc::MAP_PRIVATE | libc::MAP_ANONYMOUS | libc::MAP_NORESERVE;
    #[cfg(not(any(target_os = "linux", target_os = "android")))]
    let flags = libc::MAP_PRIVATE | libc::MAP_ANON;
    // SAFETY: a fresh anonymous mapping aliases nothing; the result is checked.
    let ptr = unsafe {
        libc::mmap(
            std::ptr::null_mut(),
            bytes,
            libc::PROT_READ | libc::PROT_WRITE,
            flags,
            -1,
            0,
        )
    };
    (ptr != libc::MAP_FAILED).then_some(ptr.cast())
}

/// Drops the pages of `base + offset .. + bytes` (page-aligned); they read as zeros again.
#[cfg(unix)]
fn unmap_pages(base: *mut u8, offset: usize, bytes: usize) -> bool {
    #[cfg(any(target_os = "linux", target_os = "android"))]
    // SAFETY: the range lies inside our own private anonymous mapping, page-aligned;
    // MADV_DONTNEED makes it read as zero-fill-on-demand, which is what the caller wants.
    unsafe {
        libc::madvise(base.add(offset).cast(), bytes, libc::MADV_DONTNEED) == 0
    }
    #[cfg(not(any(target_os = "linux", target_os = "android")))]
    {
        // Elsewhere MADV_DONTNEED need not zero the pages: write the zeros instead.
        let _ = (base, offset, bytes);
        false
    }
}

#[cfg(unix)]
fn unmap(ptr: *mut u8, bytes: usize) {
    // SAFETY: the mapping was made by map_zeroed with this length and is no longer used.
    unsafe {
        libc::munmap(ptr.cast(), bytes);
    }
}

#[cfg(not(unix))]
fn page_size() -> usize {
    4096
}

#[cfg(not(unix))]
fn map_zeroed(_bytes: usize) -> Option<*mut u8> {
    None
}

#[cfg(not(unix))]
fn unmap_pages(_base: *mut u8, _offset: usize, _bytes: usize) -> bool {
    false
}

#[cfg(not(unix))]
fn unmap(_ptr: *mut u8, _bytes: usize) {}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pages of the array the kernel holds in memory (mincore), Linux only.
    #[cfg(target_os = "linux")]
    fn resident_pages<T: Zeroable>(a: &PagedArray<T>) -> usize {
        let page = page_size();
        let pages = a.mapped.div_ceil(page);
        let mut flags = vec![0u8; pages];
        // SAFETY: the range is our own mapping; flags has one byte per page.
        let rc = unsafe { libc::mincore(a.ptr.cast(), a.mapped, flags.as_mut_ptr().cast()) };
        assert_eq!(rc, 0);
        flags.iter().filter(|&&f| f & 1 != 0).count()
    }

    /// Memory is taken where the array is written and given back where it is released:
    /// what lets a sparse grid's memory follow its particles.
    #[cfg(target_os = "linux")]
    #[test]
    fn memory_follows_writes_and_releases() {
        let page = page_size();
        // 64 MiB of address space.
        let n = (64 << 20) / 8;
        let mut a = PagedArray::<f64>::zeroed(n);
        assert!(a.mapped > 0, "not a mapping");
        // Reading takes nothing.
        assert_eq!(a.iter().step_by(4096).sum::<f64>(), 0.0);
        let before = resident_pages(&a);
        // Write one element in each of 100 pages spread over the array.
        let per_page = page / 8;
        for k in 0..100 {
            a[k * (n / 100) + 3] = 1.0;
        }
        let written = resident_pages(&a);
        // Transparent huge pages may back a write with more than one page; without them
        // exactly 100 pages.
        assert!(written >= 100, "{written} pages after 100 writes");
        assert!(
            written - before < n / per_page / 4,
            "{written} of {} pages",
            n / per_page
        );
        a.release(0..n);
        assert!(
            resident_pages(&a) <= before,
            "{} pages after release",
            resident_pages(&a)
        );
        assert!(a.iter().all(|&v| v == 0.0));
    }

    #[test]
    fn released_ranges_read_zero_and_the_rest_is_kept() {
        let n = 100_000;
        let mut a = PagedArray::<Vector<3>>::zeroed(n);
        assert!(a.iter().all(|v| *v == Vector::<3>::zeros()));
        for (i, v) in a.iter_mut().enumerate() {
            *v = Vector::<3>::repeat(i as f64 + 1.0);
        }
        // Odd bounds: neither end on a page boundary.
        a.release(1_001..77_777);
        for (i, v) in a.iter().enumerate() {
            let expected = if (1_001..77_777).contains(&i) {
                0.0
            } else {
                i as f64 + 1.0
            };
            assert_eq!(*v, Vector::<3>::repeat(expected), "element {i}");
        }
        // Written again after release.
        a[5_000] = Vector::<3>::repeat(2.0);
        assert_eq!(a[5_000][1], 2.0);
        let mut b = PagedArray::<f64>::zeroed(3);
        b[2] = 1.0;
        b.release(0..3);
        assert_eq!(&b[..], &[0.0, 0.0, 0.0]);
        assert_eq!(PagedArray::<f64>::zeroed(0).len(), 0);
    }
}
