//! Memory hints for large buffers, none of which changes a result: huge pages
//! for large result buffers where the system offers them (a fresh 200 MB pair
//! list is otherwise tens of thousands of page faults), the pages of a fresh
//! buffer mapped in one call before its first writes, and a read-ahead hint
//! for reads in random places.

/// An empty vector with room for `capacity` elements. On Linux, buffers of 4 MiB or
/// more are advised to use huge pages (`madvise(MADV_HUGEPAGE)`), which cuts the
/// page faults of the first write by a factor of 512; elsewhere, or when the advice
/// is refused, it is an ordinary vector.
pub fn large_vec<T>(capacity: usize) -> Vec<T> {
    let v = Vec::with_capacity(capacity);
    advise_huge_pages(v.as_ptr() as usize, v.capacity() * std::mem::size_of::<T>());
    v
}

/// Asks the kernel to map the whole pages inside `values` at once, before a
/// first write: one `madvise(MADV_POPULATE_WRITE)` instead of one page fault
/// per page (4 KiB on x86-64) as the writes reach them. The contents are
/// unchanged (fresh zeroed memory stays zero); a hint, ignored where refused
/// (Linux before 5.14) or elsewhere.
pub fn populate<T>(values: &mut [T]) {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: sysconf only reads a system constant
        let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) }.max(1) as usize;
        // MADV_POPULATE_WRITE only faults the pages in, as a write of their
        // own contents would; `values` is borrowed mutably meanwhile
        advise_whole_pages(
            values.as_mut_ptr() as usize,
            std::mem::size_of_val(values),
            page,
            libc::MADV_POPULATE_WRITE,
        );
    }
    #[cfg(not(target_os = "linux"))]
    let _ = values;
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
    if bytes >= 2 * HUGE {
        // MADV_HUGEPAGE changes only how the kernel backs the memory
        advise_whole_pages(start, bytes, HUGE, libc::MADV_HUGEPAGE);
    }
}

/// `madvise(advice)` over the whole pages of `page` bytes
/// inside the `bytes` from `start`, if any. `advice` must leave the contents
/// of the range as they are (the callers' hints do); the result is ignored,
/// since the memory works the same without the hint.
#[cfg(target_os = "linux")]
fn advise_whole_pages(start: usize, bytes: usize, page: usize, advice: libc::c_int) {
    let first = start.next_multiple_of(page);
    let end = (start + bytes) / page * page;
    if end > first {
        // SAFETY: the range lies inside the caller's own memory, and the
        // advice changes none of its contents (the caller's promise)
        unsafe {
            libc::madvise(first as *mut libc::c_void, end - first, advice);
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn advise_huge_pages(_start: usize, _bytes: usize) {}

/// A slice of `W n` numbers as `n` arrays of `W` (a particle's `W`
/// components side by side: `[x | alpha]` states, one-component strengths),
/// without a copy. Panics unless the length is a multiple of `W`.
pub fn as_arrays<const W: usize>(values: &[f64]) -> &[[f64; W]] {
    assert!(
        W > 0 && values.len().is_multiple_of(W),
        "{} numbers are not arrays of {W}",
        values.len()
    );
    // SAFETY: `[f64; W]` has the size of W f64 and the alignment of f64, so
    // the len / W arrays cover exactly the same memory.
    unsafe { std::slice::from_raw_parts(values.as_ptr().cast::<[f64; W]>(), values.len() / W) }
}

/// [`as_arrays`], mutable.
pub fn as_arrays_mut<const W: usize>(values: &mut [f64]) -> &mut [[f64; W]] {
    assert!(
        W > 0 && values.len().is_multiple_of(W),
        "{} numbers are not arrays of {W}",
        values.len()
    );
    // SAFETY: as in `as_arrays`; the borrow is exclusive for the result's life.
    unsafe {
        std::slice::from_raw_parts_mut(values.as_mut_ptr().cast::<[f64; W]>(), values.len() / W)
    }
}

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

    #[test]
    fn populate_and_prefetch_leave_the_contents_alone() {
        // fresh zeroed memory (straight from the kernel at this size), and
        // memory already written, from an offset that is not page-aligned
        let mut zeros = vec![0u64; 3 << 20];
        super::populate(&mut zeros[3..]);
        assert!(zeros.iter().all(|&x| x == 0));
        let mut written: Vec<u64> = (0..3 << 20).collect();
        super::populate(&mut written[5..]);
        super::prefetch(&written, 7, 2);
        super::prefetch(&written, written.len() + 9, 2);
        assert!(written.iter().enumerate().all(|(k, &x)| x == k as u64));
    }
}
