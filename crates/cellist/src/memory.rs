//! Large result buffers backed by transparent huge pages where the system offers
//! them: a fresh 200 MB pair list is otherwise tens of thousands of page faults.

/// An empty vector with room for `capacity` elements. On Linux, buffers of 4 MiB or
/// more are advised to use huge pages (`madvise(MADV_HUGEPAGE)`), which cuts the
/// page faults of the first write by a factor of 512; elsewhere, or when the advice
/// is refused, it is an ordinary vector.
pub fn large_vec<T>(capacity: usize) -> Vec<T> {
    let v = Vec::with_capacity(capacity);
    advise_huge_pages(v.as_ptr() as usize, v.capacity() * std::mem::size_of::<T>());
    v
}

/// Asks the CPU to bring the first `lines` cache lines (64 bytes each) from
/// `values[at]` on into its cache, for a read soon after: a hint with no
/// effect on results (none at all off x86-64, or past the end of `values`).
#[inline(always)]
pub fn prefetch<T>(values: &[T], at: usize, lines: usize) {
    #[cfg(target_arch = "x86_64")]
    if at < values.len() {
        let first = values[at..].as_ptr().cast::<i8>();
        for line in 0..lines {
            // SAFETY: a prefetch reads nothing the program sees and cannot
            // fault, whatever the address; SSE is part of every x86-64 CPU
            unsafe {
                std::arch::x86_64::_mm_prefetch(
                    first.wrapping_add(64 * line),
                    std::arch::x86_64::_MM_HINT_T0,
                );
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (values, at, lines);
}

#[cfg(target_os = "linux")]
fn advise_huge_pages(start: usize, bytes: usize) {
    const HUGE: usize = 2 << 20;
    if bytes < 2 * HUGE {
        return;
    }
    let first = start.next_multiple_of(HUGE);
    let end = (start + bytes) / HUGE * HUGE;
    if end > first {
        // SAFETY: the range lies inside the vector's own allocation; madvise with
        // MADV_HUGEPAGE changes only how the kernel backs it, never its contents.
        // Its result is ignored: without huge pages the memory works the same.
        unsafe {
            libc::madvise(first as *mut libc::c_void, end - first, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn advise_huge_pages(_start: usize, _bytes: usize) {}

#[cfg(test)]
mod tests {
    #[test]
    fn large_vec_is_an_ordinary_vector() {
        let mut v: Vec<u64> = super::large_vec(1 << 20);
        assert!(v.capacity() >= 1 << 20);
        v.extend(0..1000);
        assert_eq!(v[999], 999);
        let small: Vec<u8> = super::large_vec(10);
        assert!(small.is_empty());
    }
}
