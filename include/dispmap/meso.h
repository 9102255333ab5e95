#pragma once
// Mesostructure maps for per-pixel ray marching (voxel space and conventions: kernels/meso.h):
//  * MesoHeightField: a tiling height field in voxel units (from a height image);
//  * the exact Euclidean distance transform of Felzenszwalb & Huttenlocher (2012): linear
//    time, exact for sampled functions (Danielsson's 1980 vector propagation, which Donnelly
//    used, is O(n) too but not always exact; FH is, and is simpler: one lower envelope of
//    parabolas per line);
//  * DistanceMap: Donnelly's isotropic map (GPU Gems 2 ch. 8), Euclidean distances sampled at
//    (i, j, k + 1/2), read with trilinear filtering: not conservative, as in the chapter;
//  * DirectionalDistanceMap: Mehra & Kumar's conservative DDM: per voxel and direction cone the
//    distance to the nearest solid point reachable from ANY point of the voxel within the
//    cone (0 where the solid touches the voxel); the isotropic conservative map is the case of
//    one cone holding every direction. Min-filtered coarser levels keep the bound;
//  * CompressedDdm: the two-level lookup grid + atlas of blocks (§4, Appendix A);
//  * quadrics: bilinear and triangular patches as quadrics (Appendix B), one per column of the
//    height field (its bilinear patch), continuous across voxel faces because neighbouring
//    patches share their corner points.
// Every builder validates its input and throws ArgumentError naming the value.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include <glm/glm.hpp>

#include "dispmap/error.h"
#include "dispmap/kernels/meso.h"

namespace dispmap {

/// Limits of the maps (voxels per axis; cones).
inline constexpr int kMaxMesoSize = 4096;
inline constexpr int kMaxMesoLayers = 256;

namespace detail {
inline int wrapIndex(int i, int n) {
    const int r = i % n;
    return r < 0 ? r + n : r;
}
// Runs body(z) for z in [0, n) on up to two threads (the machines here have two cores).
template <class Body> void parallelLayers(int n, const Body& body) {
    const int threads = std::max(1, std::min(2, static_cast<int>(std::thread::hardware_concurrency())));
    if (threads == 1 || n < 2) {
        for (int z = 0; z < n; ++z) body(z);
        return;
    }
    std::thread other([&] {
        for (int z = 1; z < n; z += 2) body(z);
    });
    for (int z = 0; z < n; z += 2) body(z);
    other.join();
}
// The largest float <= x (x >= 0): a bound stays a bound when it is stored as a float.
inline float floatBelow(double x) {
    float f = static_cast<float>(x);
    if (static_cast<double>(f) > x) f = std::nextafter(f, 0.0f);
    return f;
}
inline void checkMesoSize(const char* what, int width, int height, int layers) {
    if (width < 2 || height < 2 || width > kMaxMesoSize || height > kMaxMesoSize)
        throw ArgumentError(std::string(what) + ": size " + std::to_string(width) + " x " + std::to_string(height) +
                            " is out of range (2 .. " + std::to_string(kMaxMesoSize) + " per axis)");
    if (layers < 2 || layers > kMaxMesoLayers)
        throw ArgumentError(std::string(what) + ": " + std::to_string(layers) + " layers is out of range (2 .. " +
                            std::to_string(kMaxMesoLayers) + ")");
}
} // namespace detail

/// A tiling height field in voxel units: heights at the texel grid points (i, j), x fastest,
/// each in [0, layers]; the surface is their periodic bilinear interpolant (kernels/meso.h).
struct MesoHeightField {
    int width = 0, height = 0, layers = 0;
    std::vector<float> h;

    float at(int x, int y) const {
        return h[static_cast<std::size_t>(detail::wrapIndex(y, height)) * static_cast<std::size_t>(width) +
                 static_cast<std::size_t>(detail::wrapIndex(x, width))];
    }
    /// Corner heights of column (i, j) in dmBilerp's order (h00, h10, h11, h01), wrapped.
    glm::vec4 cell(int i, int j) const { return {at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)}; }
    float maxHeight() const { return h.empty() ? 0.0f : *std::max_element(h.begin(), h.end()); }
};

/// A height field of width x height heights (voxels, each in [0, layers]). ArgumentError for
/// sizes out of range, a wrong count, non-finite or out-of-range heights.
inline MesoHeightField mesoHeightField(int width, int height, int layers, std::vector<float> heights) {
    detail::checkMesoSize("height field", width, height, layers);
    if (heights.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height))
        throw ArgumentError("height field: " + std::to_string(heights.size()) + " heights for " + std::to_string(width) +
                            " x " + std::to_string(height) + " texels");
    for (std::size_t i = 0; i < heights.size(); ++i)
        if (!std::isfinite(heights[i]) || heights[i] < 0.0f || heights[i] > static_cast<float>(layers))
            throw ArgumentError("height field: height " + std::to_string(heights[i]) + " at texel (" +
                                std::to_string(i % static_cast<std::size_t>(width)) + ", " +
                                std::to_string(i / static_cast<std::size_t>(width)) + ") is not finite or not in [0, " +
                                std::to_string(layers) + "]");
    MesoHeightField f;
    f.width = width;
    f.height = height;
    f.layers = layers;
    f.h = std::move(heights);
    return f;
}

/// From image values v in [0, 1] (column x, row y as stored): height = depth v, depth in
/// (0, layers] voxels (default: the whole slab).
template <class Image> MesoHeightField mesoHeightFieldFromImage(const Image& img, int layers, double depth = -1) {
    if (img.width < 1 || img.height < 1 || img.values.empty()) throw ArgumentError("height field: the image is empty");
    if (depth < 0) depth = layers;
    if (!std::isfinite(depth) || depth <= 0 || depth > layers)
        throw ArgumentError("height field: depth " + std::to_string(depth) + " is not in (0, " + std::to_string(layers) + "]");
    std::vector<float> h(img.values.size());
    for (std::size_t i = 0; i < h.size(); ++i) {
        const float v = img.values[i];
        if (!std::isfinite(v)) throw ArgumentError("height field: image value at " + std::to_string(i) + " is not finite");
        h[i] = static_cast<float>(std::clamp(static_cast<double>(v), 0.0, 1.0) * depth);
    }
    return mesoHeightField(img.width, img.height, layers, std::move(h));
}

// ------------------------------------------------------------------------------------------
// The exact distance transform.

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

/// Donnelly's distance map: for every sample (i, j, k + 1/2), i < width, j < height, k < layers,
/// the exact Euclidean distance (voxels) to the column model of the surface sampled
/// `subsamples` times per texel: the vertical half-lines {(x, y, z) : z <= H(x, y)} at the
/// points (i + a/S, j + b/S), periodic (S = 1: the height samples themselves). It approximates
/// the distance to the bilinear surface from above (overestimating it by up to ~0.7/S voxels
/// between the half-lines) and is read trilinearly, as in the chapter: no bound, which is
/// what its marchers' errors show. Samples inside the solid hold minus the distance to the
/// air's column model ({z >= H}, the same transform): with the chapter's unsigned map the
/// trilinear zero set lies on the layer centre below the surface (a stop up to a layer too
/// deep, found by the first test of this map); signed, it lies within interpolation error of
/// the surface and sphere tracing stops there (dist <= eps).
struct DistanceMap {
    int width = 0, height = 0, layers = 0, subsamples = 1;
    std::vector<float> d; // [k][j][i]
    float at(int i, int j, int k) const {
        return d[(static_cast<std::size_t>(k) * static_cast<std::size_t>(height) +
                  static_cast<std::size_t>(detail::wrapIndex(j, height))) *
                     static_cast<std::size_t>(width) +
                 static_cast<std::size_t>(detail::wrapIndex(i, width))];
    }
    std::size_t bytes() const { return d.size() * sizeof(float); }
};

/// Per layer: g(x, y) = (max(0, z - H(x, y)) S)^2 on the S-times finer grid, its 2D transform
/// (O(S^2 width height layers)), the samples at the texel grid points, divided by S.
inline DistanceMap buildDistanceMap(const MesoHeightField& hf, int subsamples = 4) {
    detail::checkMesoSize("distance map", hf.width, hf.height, hf.layers);
    if (subsamples < 1 || subsamples > 16) throw ArgumentError("distance map: subsamples " + std::to_string(subsamples) + " not in 1..16");
    DistanceMap m;
    m.width = hf.width;
    m.height = hf.height;
    m.layers = hf.layers;
    m.subsamples = subsamples;
    const int S = subsamples, fw = hf.width * S, fh = hf.height * S;
    const std::size_t slice = static_cast<std::size_t>(hf.width) * static_cast<std::size_t>(hf.height);
    std::vector<double> H(static_cast<std::size_t>(fw) * static_cast<std::size_t>(fh));
    for (int y = 0; y < fh; ++y)
        for (int x = 0; x < fw; ++x)
            H[static_cast<std::size_t>(y) * static_cast<std::size_t>(fw) + static_cast<std::size_t>(x)] =
                kern::dmBilerp(glm::dvec4(hf.cell(x / S, y / S)), glm::dvec2(double(x % S) / S, double(y % S) / S));
    m.d.resize(slice * static_cast<std::size_t>(hf.layers));
    detail::parallelLayers(hf.layers, [&](int k) {
        const double z = k + 0.5;
        std::vector<double> g(H.size()), air(H.size());
        for (std::size_t i = 0; i < g.size(); ++i) {
            const double above = std::max(0.0, z - H[i]) * S, below = std::max(0.0, H[i] - z) * S;
            g[i] = above * above;
            air[i] = below * below;
        }
        squaredDistanceTransform2D(g.data(), fw, fh);
        squaredDistanceTransform2D(air.data(), fw, fh);
        for (int j = 0; j < hf.height; ++j)
            for (int i = 0; i < hf.width; ++i) {
                const std::size_t at = static_cast<std::size_t>(j) * static_cast<std::size_t>(S) * static_cast<std::size_t>(fw) + static_cast<std::size_t>(i) * static_cast<std::size_t>(S);
                m.d[static_cast<std::size_t>(k) * slice + static_cast<std::size_t>(j * hf.width + i)] =
                    static_cast<float>(g[at] > 0 ? std::sqrt(g[at]) / S : -std::sqrt(air[at]) / S);
            }
    });
    return m;
}

// ------------------------------------------------------------------------------------------
// Direction cones and the conservative directional distance map.

/// m x n cones per hemisphere (kernels/meso.h, dmConeIndex): m azimuth sectors in {1, 2, 4, 8},
/// n elevation bands in {1, 2}; view cones (downwards) always, shadow cones (upwards) when
/// `shadow`; `isotropic`: one cone of every direction (m, n ignored).
struct ConeSet {
    int m = 4, n = 1;
    bool shadow = false;
    bool isotropic = false;

    static ConeSet all() {
        ConeSet c;
        c.isotropic = true;
        return c;
    }
    int count() const { return isotropic ? 1 : m * n * (shadow ? 2 : 1); }
    /// The m argument of dmConeIndex (0: isotropic).
    int kernelM() const { return isotropic ? 0 : m; }
    void validate() const {
        if (isotropic) return;
        if (m == 0 || n == 0) throw ArgumentError("direction cones: zero cones (" + std::to_string(m) + " x " + std::to_string(n) + ")");
        if (!(m == 1 || m == 2 || m == 4 || m == 8) || !(n == 1 || n == 2))
            throw ArgumentError("direction cones: " + std::to_string(m) + " x " + std::to_string(n) +
                                " is not supported (m in {1, 2, 4, 8}, n in {1, 2})");
    }
    std::string name() const {
        return isotropic ? std::string("isotropic") : std::to_string(m) + "x" + std::to_string(n) + (shadow ? "+shadow" : "");
    }
    /// Azimuth [lo, hi] and elevation [lo, hi] (radians; elevation < 0 below the horizon) of cone c.
    void range(int c, double az[2], double el[2]) const {
        constexpr double pi = 3.14159265358979323846;
        if (isotropic) {
            az[0] = 0;
            az[1] = 2 * pi;
            el[0] = -pi / 2;
            el[1] = pi / 2;
            return;
        }
        const int sector = c % m, band = (c / m) % n, hemisphere = c / (m * n);
        az[0] = 2 * pi * sector / m;
        az[1] = 2 * pi * (sector + 1) / m;
        const double a0 = pi / 2 * band / n, a1 = pi / 2 * (band + 1) / n; // angle from the horizon
        if (hemisphere == 0) {
            el[0] = -a1;
            el[1] = -a0;
        } else {
            el[0] = a0;
            el[1] = a1;
        }
    }
};

/// "MxN" (e.g. "4x1"; M in {1, 2, 4, 8}, N in {1, 2}) or "isotropic", with shadow cones when
/// `shadow`. ArgumentError naming the text otherwise.
inline ConeSet parseConeSet(const std::string& text, bool shadow = false) {
    if (text == "isotropic") return ConeSet::all();
    const std::size_t x = text.find('x');
    const auto digits = [](const std::string& s) {
        return !s.empty() && s.size() < 4 && std::all_of(s.begin(), s.end(), [](char ch) { return ch >= '0' && ch <= '9'; });
    };
    if (x == std::string::npos || !digits(text.substr(0, x)) || !digits(text.substr(x + 1)))
        throw ArgumentError("direction cones '" + text + "': expected MxN (e.g. 4x1) or isotropic");
    ConeSet c;
    c.m = std::stoi(text.substr(0, x));
    c.n = std::stoi(text.substr(x + 1));
    c.shadow = shadow;
    c.validate();
    return c;
}

/// Conservative directional distances: d[c][k][j][i] <= the distance along any ray that starts
/// anywhere in voxel (i, j, k) with a direction in cone c to the first solid point it meets;
/// capped at `cap` (the cap is itself a bound). 0 where the solid touches the voxel.
struct DirectionalDistanceMap {
    int width = 0, height = 0, layers = 0;
    ConeSet cones;
    float cap = 0;
    std::vector<float> d;

    std::size_t index(int c, int i, int j, int k) const {
        return ((static_cast<std::size_t>(c) * static_cast<std::size_t>(layers) + static_cast<std::size_t>(k)) *
                    static_cast<std::size_t>(height) +
                static_cast<std::size_t>(detail::wrapIndex(j, height))) *
                   static_cast<std::size_t>(width) +
               static_cast<std::size_t>(detail::wrapIndex(i, width));
    }
    float at(int c, int i, int j, int k) const { return d[index(c, i, j, k)]; }
    std::size_t bytes() const { return d.size() * sizeof(float); }
};

namespace detail {
struct Box {
    glm::dvec3 lo, hi;
};
inline double wrapAngle(double a) {
    constexpr double pi = 3.14159265358979323846;
    while (a <= -pi) a += 2 * pi;
    while (a > pi) a -= 2 * pi;
    return a;
}
// Whether some direction x / |x|, x in the box D (not containing 0), can lie in the cone
// [az] x [el]: the box's elevation and azimuth intervals (bounds of the true sets) overlap
// the cone's. Conservative: it may say yes for a box that misses the cone, never no for one
// that meets it.
inline bool boxMeetsCone(const Box& D, const double az[2], const double el[2]) {
    constexpr double pi = 3.14159265358979323846, slack = 1e-6; // > float rounding of dmConeIndex's tests
    const double cx = std::clamp(0.0, D.lo.x, D.hi.x), cy = std::clamp(0.0, D.lo.y, D.hi.y);
    const double rhoMin = std::sqrt(cx * cx + cy * cy);
    const double mx = std::max(std::abs(D.lo.x), std::abs(D.hi.x)), my = std::max(std::abs(D.lo.y), std::abs(D.hi.y));
    const double rhoMax = std::sqrt(mx * mx + my * my);
    const double elMax = D.hi.z >= 0 ? std::atan2(D.hi.z, rhoMin) : std::atan2(D.hi.z, rhoMax);
    const double elMin = D.lo.z <= 0 ? std::atan2(D.lo.z, rhoMin) : std::atan2(D.lo.z, rhoMax);
    if (elMax < el[0] - slack || elMin > el[1] + slack) return false;
    if (rhoMin == 0 || az[1] - az[0] >= 2 * pi - slack) return true;
    const double centre = std::atan2(0.5 * (D.lo.y + D.hi.y), 0.5 * (D.lo.x + D.hi.x));
    double lo = 0, hi = 0;
    const double xs[2] = {D.lo.x, D.hi.x}, ys[2] = {D.lo.y, D.hi.y};
    for (double x : xs)
        for (double y : ys) {
            const double delta = wrapAngle(std::atan2(y, x) - centre);
            lo = std::min(lo, delta);
            hi = std::max(hi, delta);
        }
    for (double shift : {-2 * pi, 0.0, 2 * pi}) {
        const double a = centre + lo + shift, b = centre + hi + shift;
        if (a <= az[1] + slack && b >= az[0] - slack) return true;
    }
    return false;
}
inline double boxDistance(const Box& D) {
    const glm::dvec3 c = glm::clamp(glm::dvec3(0.0), D.lo, D.hi);
    return glm::length(c);
}
} // namespace detail

/// Builds the conservative DDM of a height field. The solid of column (i, j) lies inside the
/// boxes of its `subcells` x `subcells` sub-rectangles, each from -Inf up to the largest
/// height of the bilinear patch over it (at one of its corners); for each voxel V and cone C
/// the map stores the smallest distance |x| over the difference boxes D = box - V whose
/// directions may lie in C (detail::boxMeetsCone), found by a search in rings of columns
/// that stops when the ring is farther than the best. Cap default: `layers` voxels.
inline DirectionalDistanceMap buildDdm(const MesoHeightField& hf, const ConeSet& cones, int subcells = 2, float cap = 0) {
    detail::checkMesoSize("directional distance map", hf.width, hf.height, hf.layers);
    cones.validate();
    if (subcells < 1 || subcells > 8) throw ArgumentError("directional distance map: subcells " + std::to_string(subcells) + " not in 1..8");
    if (!(cap >= 0) || !std::isfinite(cap)) throw ArgumentError("directional distance map: cap must be finite and >= 0");
    DirectionalDistanceMap m;
    m.width = hf.width;
    m.height = hf.height;
    m.layers = hf.layers;
    m.cones = cones;
    m.cap = cap > 0 ? cap : static_cast<float>(hf.layers);
    m.d.assign(static_cast<std::size_t>(cones.count()) * static_cast<std::size_t>(hf.width) *
                   static_cast<std::size_t>(hf.height) * static_cast<std::size_t>(hf.layers),
               m.cap);
    // Tops of the sub-boxes and of the whole column, per column.
    const int S = subcells;
    std::vector<double> subTop(static_cast<std::size_t>(hf.width * hf.height * S * S)), cellTop(static_cast<std::size_t>(hf.width * hf.height));
    std::vector<double> cellMin(cellTop.size());
    for (int j = 0; j < hf.height; ++j)
        for (int i = 0; i < hf.width; ++i) {
            const glm::dvec4 h = glm::dvec4(hf.cell(i, j));
            const auto H = [&](double x, double y) { return kern::dmBilerp(h, glm::dvec2(x, y)); };
            double top = 0;
            for (int b = 0; b < S; ++b)
                for (int a = 0; a < S; ++a) {
                    const double x0 = double(a) / S, x1 = double(a + 1) / S, y0 = double(b) / S, y1 = double(b + 1) / S;
                    const double t = std::max(std::max(H(x0, y0), H(x1, y0)), std::max(H(x1, y1), H(x0, y1)));
                    subTop[((static_cast<std::size_t>(j) * static_cast<std::size_t>(hf.width) + static_cast<std::size_t>(i)) * static_cast<std::size_t>(S) + static_cast<std::size_t>(b)) * static_cast<std::size_t>(S) + static_cast<std::size_t>(a)] = t;
                    top = std::max(top, t);
                }
            cellTop[static_cast<std::size_t>(j * hf.width + i)] = top;
            cellMin[static_cast<std::size_t>(j * hf.width + i)] = std::min(std::min(h.x, h.y), std::min(h.z, h.w));
        }
    const double bottom = -4.0 * hf.layers - 1.0;
    const int C = cones.count();
    detail::parallelLayers(hf.layers, [&](int k) {
        for (int c = 0; c < C; ++c) {
            double az[2], el[2];
            cones.range(c, az, el);
            for (int j = 0; j < hf.height; ++j)
                for (int i = 0; i < hf.width; ++i) {
                    if (k + 1 <= cellMin[static_cast<std::size_t>(j * hf.width + i)]) {
                        m.d[m.index(c, i, j, k)] = 0; // inside the solid
                        continue;
                    }
                    double best = m.cap;
                    const int maxRing = static_cast<int>(std::ceil(best)) + 1;
                    for (int r = 0; r <= maxRing && r - 1 < best; ++r) {
                        for (int dj = -r; dj <= r; ++dj)
                            for (int di = -r; di <= r; ++di) {
                                if (std::max(std::abs(di), std::abs(dj)) != r) continue;
                                const int ci = i + di, cj = j + dj;
                                const std::size_t cell = static_cast<std::size_t>(detail::wrapIndex(cj, hf.height) * hf.width +
                                                                                  detail::wrapIndex(ci, hf.width));
                                const detail::Box cellBox{{ci - (i + 1.0), cj - (j + 1.0), bottom - (k + 1.0)},
                                                          {ci + 1.0 - i, cj + 1.0 - j, cellTop[cell] - k}};
                                if (detail::boxDistance(cellBox) >= best || !detail::boxMeetsCone(cellBox, az, el)) continue;
                                for (int b = 0; b < S; ++b)
                                    for (int a = 0; a < S; ++a) {
                                        const double x0 = ci + double(a) / S, y0 = cj + double(b) / S;
                                        const detail::Box D{{x0 - (i + 1.0), y0 - (j + 1.0), bottom - (k + 1.0)},
                                                            {x0 + 1.0 / S - i, y0 + 1.0 / S - j,
                                                             subTop[cell * static_cast<std::size_t>(S * S) + static_cast<std::size_t>(b * S + a)] - k}};
                                        const double dist = detail::boxDistance(D);
                                        if (dist < best && detail::boxMeetsCone(D, az, el)) best = dist;
                                    }
                            }
                    }
                    m.d[m.index(c, i, j, k)] = detail::floatBelow(best);
                }
        }
    });
    return m;
}

/// The next coarser level (Mehra & Kumar §3.1, "min filter"): each voxel of the half-size map
/// holds the minimum of its 2 x 2 x 2 children, which is again conservative for the union of
/// their boxes, in the coarse map's own voxels (halved: exact). Needs even sizes.
inline DirectionalDistanceMap minFilter(const DirectionalDistanceMap& fine) {
    if (fine.width % 2 || fine.height % 2 || fine.layers % 2 || fine.width < 4 || fine.height < 4 || fine.layers < 4)
        throw ArgumentError("minFilter: sizes " + std::to_string(fine.width) + " x " + std::to_string(fine.height) + " x " +
                            std::to_string(fine.layers) + " must be even and >= 4");
    DirectionalDistanceMap m;
    m.width = fine.width / 2;
    m.height = fine.height / 2;
    m.layers = fine.layers / 2;
    m.cones = fine.cones;
    m.cap = 0.5f * fine.cap;
    m.d.resize(fine.d.size() / 8);
    for (int c = 0; c < fine.cones.count(); ++c)
        for (int k = 0; k < m.layers; ++k)
            for (int j = 0; j < m.height; ++j)
                for (int i = 0; i < m.width; ++i) {
                    float v = std::numeric_limits<float>::infinity();
                    for (int e = 0; e < 8; ++e) v = std::min(v, fine.at(c, 2 * i + (e & 1), 2 * j + (e >> 1 & 1), 2 * k + (e >> 2)));
                    m.d[m.index(c, i, j, k)] = 0.5f * v;
                }
    return m;
}

/// The two-level compressed DDM (Mehra & Kumar §4, Algorithms A.1 / A.2): per cone a lookup
/// grid of block x block x block blocks; a block holding both 0 and non-zero values (a surface
/// may pass through it) is stored whole in the atlas and its grid word holds its atlas index
/// with bit 31 set; a block of zeros only (inside the solid) keeps 0, and any other block only
/// its minimum (the word holds the float's bits), which is again conservative. Atlas voxels
/// and zero blocks read back bit for bit; the rest read their block's minimum.
struct CompressedDdm {
    int width = 0, height = 0, layers = 0, block = 4;
    int gx = 0, gy = 0, gz = 0; ///< grid size in blocks
    ConeSet cones;
    std::vector<std::uint32_t> grid; ///< [cone][bz][by][bx]
    std::vector<float> atlas;        ///< blocks of block^3 values, x fastest

    std::size_t gridIndex(int c, int bx, int by, int bz) const {
        return ((static_cast<std::size_t>(c) * static_cast<std::size_t>(gz) + static_cast<std::size_t>(bz)) *
                    static_cast<std::size_t>(gy) +
                static_cast<std::size_t>(by)) *
                   static_cast<std::size_t>(gx) +
               static_cast<std::size_t>(bx);
    }
    /// Appendix A.2 on voxel (i, j, k), i and j wrapped; k in [0, layers).
    float lookup(int c, int i, int j, int k) const {
        i = detail::wrapIndex(i, width);
        j = detail::wrapIndex(j, height);
        int atlasIndex = -1;
        const float d = kern::dmGridWordDistance(grid[gridIndex(c, i / block, j / block, k / block)], atlasIndex);
        if (atlasIndex < 0) return d;
        const int b = block;
        return atlas[static_cast<std::size_t>(atlasIndex) * static_cast<std::size_t>(b * b * b) +
                     static_cast<std::size_t>(((k % b) * b + j % b) * b + i % b)];
    }
    std::size_t uncompressedBytes() const {
        return static_cast<std::size_t>(cones.count()) * static_cast<std::size_t>(width) * static_cast<std::size_t>(height) *
               static_cast<std::size_t>(layers) * sizeof(float);
    }
    std::size_t bytes() const { return grid.size() * sizeof(std::uint32_t) + atlas.size() * sizeof(float); }
    double ratio() const { return static_cast<double>(uncompressedBytes()) / static_cast<double>(std::max<std::size_t>(bytes(), 1)); }
    std::size_t atlasBlocks() const { return atlas.size() / static_cast<std::size_t>(block * block * block); }
};

inline CompressedDdm compressDdm(const DirectionalDistanceMap& m, int block = 4) {
    if (block < 1 || block > 32 || m.width % block || m.height % block || m.layers % block)
        throw ArgumentError("compressDdm: block " + std::to_string(block) + " must divide " + std::to_string(m.width) + " x " +
                            std::to_string(m.height) + " x " + std::to_string(m.layers));
    CompressedDdm c;
    c.width = m.width;
    c.height = m.height;
    c.layers = m.layers;
    c.block = block;
    c.cones = m.cones;
    c.gx = m.width / block;
    c.gy = m.height / block;
    c.gz = m.layers / block;
    c.grid.resize(static_cast<std::size_t>(m.cones.count()) * static_cast<std::size_t>(c.gx) * static_cast<std::size_t>(c.gy) *
                  static_cast<std::size_t>(c.gz));
    const std::size_t atlasMax = (std::size_t(1) << 31) - 1;
    for (int cone = 0; cone < m.cones.count(); ++cone)
        for (int bz = 0; bz < c.gz; ++bz)
            for (int by = 0; by < c.gy; ++by)
                for (int bx = 0; bx < c.gx; ++bx) {
                    float lo = std::numeric_limits<float>::infinity();
                    for (int k = 0; k < block; ++k)
                        for (int j = 0; j < block; ++j)
                            for (int i = 0; i < block; ++i)
                                lo = std::min(lo, m.at(cone, bx * block + i, by * block + j, bz * block + k));
                    float hi = 0.0f;
                    for (int k = 0; k < block; ++k)
                        for (int j = 0; j < block; ++j)
                            for (int i = 0; i < block; ++i)
                                hi = std::max(hi, m.at(cone, bx * block + i, by * block + j, bz * block + k));
                    std::uint32_t word;
                    if (lo > 0.0f || hi == 0.0f) { // free space, or all 0 (inside the solid): one value
                        std::memcpy(&word, &lo, sizeof word);
                    } else {
                        const std::size_t index = c.atlasBlocks();
                        if (index > atlasMax) throw ArgumentError("compressDdm: more than 2^31 atlas blocks");
                        for (int k = 0; k < block; ++k)
                            for (int j = 0; j < block; ++j)
                                for (int i = 0; i < block; ++i)
                                    c.atlas.push_back(m.at(cone, bx * block + i, by * block + j, bz * block + k));
                        word = 0x80000000u | static_cast<std::uint32_t>(index);
                    }
                    c.grid[c.gridIndex(cone, bx, by, bz)] = word;
                }
    return c;
}

// ------------------------------------------------------------------------------------------
// Quadrics (Mehra & Kumar Eq. 1 and Appendix B).

/// Q(p) = A x^2 + B y^2 + C z^2 + D xy + E yz + F zx + G x + H y + I z + J in the kernels'
/// packing: a = (A, B, C, D), b = (E, F, G, H), c = (I, J, ., .).
struct Quadric {
    glm::dvec4 a{0}, b{0}, c{0};
    double operator()(const glm::dvec3& p) const { return kern::dmQuadricValue(a, b, c, p); }
};

namespace detail {
// (alpha . X + alpha0)(beta . X + beta0) + gamma . X + gamma0, expanded.
inline Quadric productQuadric(const glm::dvec3& al, double al0, const glm::dvec3& be, double be0, const glm::dvec3& ga, double ga0) {
    Quadric q;
    q.a = {al.x * be.x, al.y * be.y, al.z * be.z, al.x * be.y + al.y * be.x};
    q.b = {al.y * be.z + al.z * be.y, al.z * be.x + al.x * be.z, al.x * be0 + al0 * be.x + ga.x, al.y * be0 + al0 * be.y + ga.y};
    q.c = {al.z * be0 + al0 * be.z + ga.z, al0 * be0 + ga0, 0, 0};
    return q;
}
// Scales q so its largest coefficient is 1 in magnitude and it grows from the patch point
// `on` towards `inside` (its gradient there: a far probe point could lie beyond the fold of
// a twisted patch's quadric).
inline Quadric normalised(Quadric q, const glm::dvec3& on, const glm::dvec3& inside) {
    double big = 0;
    for (int i = 0; i < 4; ++i) big = std::max({big, std::abs(q.a[i]), std::abs(q.b[i])});
    big = std::max({big, std::abs(q.c.x), std::abs(q.c.y)});
    if (!(big > 0) || !std::isfinite(big)) throw ArgumentError("quadric: degenerate patch (no finite coefficient)");
    const glm::dvec3 p = on;
    const glm::dvec3 grad(2 * q.a.x * p.x + q.a.w * p.y + q.b.y * p.z + q.b.z, 2 * q.a.y * p.y + q.a.w * p.x + q.b.x * p.z + q.b.w,
                          2 * q.a.z * p.z + q.b.x * p.y + q.b.y * p.x + q.c.x);
    const double s = (glm::dot(grad, inside - on) < 0 ? -1.0 : 1.0) / big;
    q.a *= s;
    q.b *= s;
    q.c.x *= s;
    q.c.y *= s;
    return q;
}
} // namespace detail

/// Appendix B: the quadric of the bilinear patch (1-u)(1-v) P1 + u(1-v) P2 + uv P3 + (1-u)v P4,
/// positive on the side of `inside` (a point off the patch, judged at the patch's centre). Derivation (the paper's appendix
/// gives only the substitution): with Y = X - P1, a = P1 + P3 - P2 - P4, b = P2 - P1,
/// c = P4 - P1, n = b x c, gu = (c x n)/|n|^2, gv = (n x b)/|n|^2, gw = n/|n|^2 and ka = gu.a,
/// kb = gv.a, kn = gw.a, the patch has gu.Y = u + ka uv, gv.Y = v + kb uv, gw.Y = kn uv, so
/// F = (gu.Y - (ka/kn) gw.Y)(kn gv.Y - kb gw.Y) - gw.Y = u (kn v) - kn uv = 0 on it. F is
/// normalised by kn (the unnormalised product form vanishes identically as the patch flattens);
/// a patch with |kn| <= 1e-12 (|ka| + |kb| + 1) is planar and becomes its plane gw.Y = 0.
/// ArgumentError when b and c are parallel (no plane).
inline Quadric bilinearPatchQuadric(const glm::dvec3& P1, const glm::dvec3& P2, const glm::dvec3& P3, const glm::dvec3& P4,
                                    const glm::dvec3& inside) {
    const glm::dvec3 a = P1 + P3 - P2 - P4, b = P2 - P1, c = P4 - P1, n = glm::cross(b, c);
    const double nn = glm::dot(n, n);
    if (!(nn > 1e-24 * glm::dot(b, b) * glm::dot(c, c)) || !std::isfinite(nn))
        throw ArgumentError("bilinearPatchQuadric: the patch's edges P2 - P1 and P4 - P1 are parallel or not finite");
    const glm::dvec3 centre = 0.25 * (P1 + P2 + P3 + P4);
    const glm::dvec3 gu = glm::cross(c, n) / nn, gv = glm::cross(n, b) / nn, gw = n / nn;
    const double ka = glm::dot(gu, a), kb = glm::dot(gv, a), kn = glm::dot(gw, a);
    if (std::abs(kn) <= 1e-12 * (std::abs(ka) + std::abs(kb) + 1))
        return detail::normalised(detail::productQuadric(glm::dvec3(0), 0, glm::dvec3(0), 0, gw, -glm::dot(gw, P1)), centre, inside);
    const glm::dvec3 al = gu - (ka / kn) * gw, be = kn * gv - kb * gw;
    return detail::normalised(detail::productQuadric(al, -glm::dot(al, P1), be, -glm::dot(be, P1), -gw, glm::dot(gw, P1)), centre,
                              inside);
}

/// Appendix B for a triangle u P1 + v P2 + (1-u-v) P3: its plane, positive on the side of `inside`.
inline Quadric triangleQuadric(const glm::dvec3& P1, const glm::dvec3& P2, const glm::dvec3& P3, const glm::dvec3& inside) {
    const glm::dvec3 n = glm::cross(P2 - P1, P3 - P1);
    if (!(glm::dot(n, n) > 0) || !std::isfinite(glm::dot(n, n))) throw ArgumentError("triangleQuadric: degenerate triangle");
    return detail::normalised(detail::productQuadric(glm::dvec3(0), 0, glm::dvec3(0), 0, n, -glm::dot(n, P1)), (P1 + P2 + P3) / 3.0,
                              inside);
}

/// One quadric per column of a height field (its bilinear patch), in the column's frame
/// (x - i, y - j, z); q[3 (j width + i) + 0..2] = (a, b, c) with c.z, c.w = the lowest and
/// highest corner height (dmVoxelQuadric). Neighbouring columns share their corner points,
/// so the surface is C0 across voxel faces.
struct ColumnQuadrics {
    int width = 0, height = 0;
    std::vector<glm::vec4> q;
    std::size_t bytes() const { return q.size() * sizeof(glm::vec4); }
};

inline ColumnQuadrics buildColumnQuadrics(const MesoHeightField& hf) {
    ColumnQuadrics out;
    out.width = hf.width;
    out.height = hf.height;
    out.q.resize(static_cast<std::size_t>(hf.width) * static_cast<std::size_t>(hf.height) * 3);
    for (int j = 0; j < hf.height; ++j)
        for (int i = 0; i < hf.width; ++i) {
            const glm::dvec4 h(hf.cell(i, j));
            const double lo = std::min(std::min(h.x, h.y), std::min(h.z, h.w)), hi = std::max(std::max(h.x, h.y), std::max(h.z, h.w));
            const Quadric Q = bilinearPatchQuadric({0, 0, h.x}, {1, 0, h.y}, {1, 1, h.z}, {0, 1, h.w}, {0.5, 0.5, lo - 1.0});
            const std::size_t at = 3 * (static_cast<std::size_t>(j) * static_cast<std::size_t>(hf.width) + static_cast<std::size_t>(i));
            out.q[at] = glm::vec4(Q.a);
            out.q[at + 1] = glm::vec4(Q.b);
            out.q[at + 2] = glm::vec4(static_cast<float>(Q.c.x), static_cast<float>(Q.c.y), static_cast<float>(lo), static_cast<float>(hi));
        }
    return out;
}

} // namespace dispmap
