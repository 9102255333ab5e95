#pragma once
// The exact Euclidean distance transform of Felzenszwalb & Huttenlocher (2012): linear time,
// exact for sampled functions (Danielsson's 1980 vector propagation, which Donnelly used, is
// O(n) too but not always exact; FH is, and is simpler: one lower envelope of parabolas per
// line). GLM only.
#include <cmath>
#include <limits>
#include <vector>

#include "dispmap/meso/height_field.h"

namespace dispmap {

/// Felzenszwalb & Huttenlocher's 1D transform: d[q] = min_p (w2 (q - p)^2 + f[p]) for q in
/// [0, n), f[p] = +Inf allowed (no feature; all +Inf gives all +Inf). Exact: the lower envelope
/// of the parabolas rooted at (p, f[p]), built left to right. v, z: scratch of n and n + 1.
inline void distanceTransform1D(const double* f, int n, double w2, double* d, int* v, double* z) {
    const double inf = std::numeric_limits<double>::infinity();
    int k = -1;
    for (int q = 0; q < n; ++q) {
        if (!(f[q] < inf)) continue;
        if (k < 0) {
            k = 0;
            v[0] = q;
            z[0] = -inf;
            z[1] = inf;
            continue;
        }
        double s = 0;
        for (;;) {
            const double p = v[k];
            s = ((f[q] + w2 * q * q) - (f[v[k]] + w2 * p * p)) / (2.0 * w2 * (q - p));
            if (s <= z[k] && k > 0) {
                --k;
                continue;
            }
            break;
        }
        if (s <= z[k]) { // k == 0 and z[0] = -Inf: cannot happen for finite s; kept for clarity
            v[0] = q;
            continue;
        }
        ++k;
        v[k] = q;
        z[k] = s;
        z[k + 1] = inf;
    }
    if (k < 0) {
        std::fill(d, d + n, inf);
        return;
    }
    int j = 0;
    for (int q = 0; q < n; ++q) {
        while (z[j + 1] < q) ++j;
        const double dq = q - v[j];
        d[q] = w2 * dq * dq + f[v[j]];
    }
}

namespace detail {
// The 1D transform along a periodic line of n values (stride `stride` in `data`, in place):
// the line is padded with `pad` wrapped copies on each side, so a feature up to `pad` away
// across the seam counts.
struct PeriodicLine {
    std::vector<double> f, d, z;
    std::vector<int> v;
    void run(double* data, int n, std::ptrdiff_t stride, int pad) {
        const int m = n + 2 * pad;
        f.resize(static_cast<std::size_t>(m));
        d.resize(static_cast<std::size_t>(m));
        z.resize(static_cast<std::size_t>(m) + 1);
        v.resize(static_cast<std::size_t>(m));
        for (int q = 0; q < m; ++q) f[static_cast<std::size_t>(q)] = data[wrapIndex(q - pad, n) * stride];
        distanceTransform1D(f.data(), m, 1.0, d.data(), v.data(), z.data());
        for (int q = 0; q < n; ++q) data[q * stride] = d[static_cast<std::size_t>(q + pad)];
    }
};
} // namespace detail

/// Squared Euclidean distance transform of a periodic 2D function g (nx x ny, x fastest):
/// out(x, y) = min over (i, j) and periods of (x - i)^2 + (y - j)^2 + g(i, j). Exact (FH, x
/// pass then y pass). g = +Inf where there is no feature.
inline void squaredDistanceTransform2D(double* g, int nx, int ny) {
    detail::PeriodicLine line;
    // Across the seam the nearest copy of a feature is at most n/2 away per axis.
    for (int y = 0; y < ny; ++y) line.run(g + static_cast<std::ptrdiff_t>(y) * nx, nx, 1, nx / 2 + 1);
    for (int x = 0; x < nx; ++x) line.run(g + x, ny, nx, ny / 2 + 1);
}

} // namespace dispmap
