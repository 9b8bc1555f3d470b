//! Cache hints: [`prefetch`], a request to fetch the cache line holding an address
//! before it is read. A hint only: it never faults and changes no result, so the
//! units use it where the next access is known ahead of time (the GP's walk of the
//! static tree, the VP's video memory under the next polygon).

/// Bytes of a cache line (x86-64's, and most others'): the step of a run of hints.
pub(crate) const LINE: usize = 64;

/// A hint to fetch the cache line holding `p` (never faults, whatever `p` is; no
/// effect on any result). Nothing on other processors.
#[inline(always)]
pub(crate) fn prefetch(p: *const u8) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch reads nothing the program sees and never faults, even for
    // an address outside any allocation; SSE is in every x86-64 processor.
    #[allow(unsafe_code, reason = "a cache hint, which needs a raw pointer")]
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p.cast::<i8>());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}
