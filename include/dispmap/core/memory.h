#pragma once
// Large output arrays that are filled once and read many times (a tessellation's vertices and
// triangles: tens to hundreds of MiB at high factors).
//
// Fresh memory costs its first touch: the kernel faults in and zeroes every page. With 4 KiB
// pages that is one fault per 4 KiB, and on a virtual machine a fault is several microseconds.
// reserveLarge() asks Linux for transparent huge pages on the array (madvise MADV_HUGEPAGE, a
// hint: it does nothing where THP is "never", or on other systems), so the same memory takes
// 512 times fewer faults: a factor-64 tessellation of Spot into a new mesh ran 2.3-2.4x faster with
// the hint on the 2-core VM here (`dispmap bench --only embree`, its "First touch" lines). Only
// whole 2 MiB-aligned ranges inside the array are advised, so no memory is added. The capacity
// reserved is virtual until touched: an upper bound costs nothing for the part never written.
#include <cstddef>
#include <cstdint>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace dispmap {

/// Arrays smaller than this are left to malloc as they are: none holds a whole huge page (2 MiB).
inline constexpr std::size_t kHugePageArrayBytes = std::size_t{2} << 20;

/// Hints that [p, p + bytes) is one large array: transparent huge pages for the 2 MiB-aligned
/// part of it on Linux, nothing elsewhere or below kHugePageArrayBytes. Never fails (a refused
/// hint only leaves the pages small).
inline void adviseHugePages(void* p, std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    if (!p || bytes < kHugePageArrayBytes) return;
    constexpr std::uintptr_t huge = std::uintptr_t{2} << 20;
    const std::uintptr_t a = reinterpret_cast<std::uintptr_t>(p);
    const std::uintptr_t lo = (a + huge - 1) & ~(huge - 1), hi = (a + bytes) & ~(huge - 1);
    if (hi > lo) (void)madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_HUGEPAGE);
#else
    (void)p;
    (void)bytes;
#endif
}

/// v.reserve(n), with the huge-page hint (when `hint`) on a new allocation of at least
/// kHugePageArrayBytes. For an empty vector (the tessellator clears its arrays first) the hint
/// goes in before anything is written to the new block, so its first touch already faults huge
/// pages; a vector with elements copies them into the block before the hint.
///
/// Where the hint does nothing or costs: THP "never" ignores it and "always" gives huge pages
/// without it; with the kernel's default defrag setting ("madvise") a fault in an advised range
/// may compact memory first, which can stall on a fragmented machine; the 2 MiB size is x86-64's
/// (arm64 with 64 KiB base pages has 512 MiB huge pages, and the hint then rarely applies). On
/// memory malloc keeps in its heap after a free, the advice stays with the range.
template <class T, class A> void reserveLarge(std::vector<T, A>& v, std::size_t n, bool hint = true) {
    if (v.capacity() >= n) return;
    v.reserve(n);
    if (hint) adviseHugePages(v.data(), v.capacity() * sizeof(T));
}

/// reserveLarge(v, n, hint), then v.resize(n).
template <class T, class A> void resizeLarge(std::vector<T, A>& v, std::size_t n, bool hint = true) {
    reserveLarge(v, n, hint);
    v.resize(n);
}

} // namespace dispmap
